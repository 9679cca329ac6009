// sirad: a per-key rate limit (see rate_limit.h).
#include "cluster/rate_limit.h"

#include <algorithm>

namespace sirad::cluster {

bool RateLimit::allow(const std::string& key, double now, uint64_t* suppressed) {
  auto it = keys_.find(key);
  if (it == keys_.end()) {
    if (keys_.size() >= max_keys_) {
      auto oldest = std::min_element(keys_.begin(), keys_.end(), [](const auto& a, const auto& b) { return a.second.last < b.second.last; });
      keys_.erase(oldest);
    }
    it = keys_.emplace(key, Key{now, 0, 0, now}).first;
  }
  Key& k = it->second;
  k.last = now;
  if (now - k.window_start >= window_s_) {
    k.window_start = now;
    k.in_window = 0;
  }
  if (k.in_window >= burst_) {
    ++k.held;
    return false;
  }
  ++k.in_window;
  if (suppressed) *suppressed = k.held;
  k.held = 0;
  return true;
}

std::vector<std::pair<std::string, uint64_t>> RateLimit::held() const {
  std::vector<std::pair<std::string, uint64_t>> out;
  for (const auto& [key, k] : keys_)
    if (k.held > 0) out.emplace_back(key, k.held);
  return out;
}

}  // namespace sirad::cluster
