// sirad: grants' due times (see deadlines.h).
#include "cluster/deadlines.h"

#include <algorithm>

#include <fmt/format.h>

namespace sirad::cluster {

double Deadlines::add(uint32_t node, uint64_t grant, double now, double bound_s) {
  auto& due = due_[node];
  const double from = due.empty() ? now : std::max(now, due.back().second - rules_.slack_s);
  const double at = from + bound_s + rules_.slack_s;
  due.emplace_back(grant, at);
  return at;
}

void Deadlines::settle(uint32_t node, uint64_t grant) {
  auto it = due_.find(node);
  if (it == due_.end()) return;
  std::erase_if(it->second, [&](const auto& d) { return d.first == grant; });
  if (it->second.empty()) due_.erase(it);
}

bool Deadlines::holds(uint32_t node) const { return due_.count(node) > 0; }

std::string Deadlines::overdue(uint32_t node, double at) const {
  auto it = due_.find(node);
  if (it == due_.end() || !(at > it->second.front().second)) return "";
  return fmt::format("grant {} overdue by {:.1f} s", it->second.front().first, at - it->second.front().second);
}

bool Deadlines::tighten(const std::vector<uint32_t>& nodes, double now, double measured_s) {
  bool moved = false;
  for (uint32_t n : nodes) {
    auto it = due_.find(n);
    if (it == due_.end()) continue;
    for (std::size_t k = 0; k < it->second.size(); ++k) {
      const double at = now + rules_.slack_s + static_cast<double>(k + 1) * rules_.unequal_first * measured_s;
      if (at < it->second[k].second) it->second[k].second = at, moved = true;
    }
  }
  return moved;
}

}  // namespace sirad::cluster
