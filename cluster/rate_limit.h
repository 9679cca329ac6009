// sirad: a per-key rate limit with time passed in (no clock): at most `burst` events per key
// in any window of `window_s` seconds; the rest are counted, so the caller can say how many it
// suppressed. Keys beyond `max_keys` evict the one seen longest ago, so a flood of new keys
// (routing ids) costs bounded memory. The coordinator uses it for its log lines about peers,
// so 20,000 garbage messages give a few lines, not 20,000.
#pragma once
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace sirad::cluster {

class RateLimit {
 public:
  RateLimit(uint32_t burst, double window_s, std::size_t max_keys = 4096)
      : burst_(burst), window_s_(window_s), max_keys_(max_keys) {}

  // True when the event may go (log it); false when it is over the limit (counted).
  // `suppressed`, when the event goes, is set to how many of this key's events were held back
  // since the last one that went (0 for none).
  bool allow(const std::string& key, double now, uint64_t* suppressed = nullptr);

  std::size_t keys() const { return keys_.size(); }
  // Every key with events held back since its last one went, and how many (at the end of a run).
  std::vector<std::pair<std::string, uint64_t>> held() const;

 private:
  struct Key {
    double window_start = 0;
    uint32_t in_window = 0;
    uint64_t held = 0;
    double last = 0;
  };
  uint32_t burst_;
  double window_s_;
  std::size_t max_keys_;
  std::map<std::string, Key> keys_;
};

}  // namespace sirad::cluster
