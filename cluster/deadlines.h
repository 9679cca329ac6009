// sirad: when each node's outstanding grants are due (PROTOCOL.md section 4), for bundles and
// tiles alike, free of sockets and clocks: times are seconds on the caller's clock (the real
// coordinator's steady clock since its start, or a virtual one). A node past a grant's due time
// is declared dead (or dropped from the image) and its work granted again.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace sirad::cluster {

// What a grant may take beyond the work's own bound.
struct DeadlineRules {
  // The least a due time allows beyond its bound: the liveness window, and at least 10 s (a
  // loaded machine can stall an honest node for seconds; a node declared dead for it rejoins,
  // but its grant would run twice).
  double slack_s = 10;
  // A node's first grant, before any node has measured one: PoCL compiles a kernel for its
  // work-group size at its first use (seconds at an empty POCL_CACHE_DIR, several times that
  // under load).
  double first_grant_s = 30;
  // Once one node has measured its first grant (or its time per tile), the first grants of the
  // nodes that have measured none are due this many times that (tighten).
  double unequal_first = 16;
};

// The outstanding grants of every node, oldest first, each with its due time.
class Deadlines {
 public:
  explicit Deadlines(DeadlineRules rules = {}) : rules_(rules) {}
  const DeadlineRules& rules() const { return rules_; }

  // A grant `grant` to `node` at `now` whose work takes `bound_s`: it runs after the node's
  // grants before it (queued behind the last one's bound), so it is due at
  // max(now, last due - slack) + bound_s + slack. Returns the due time.
  double add(uint32_t node, uint64_t grant, double now, double bound_s);
  // `node`'s grant `grant` is answered (no longer due); nothing when it holds no such grant.
  void settle(uint32_t node, uint64_t grant);
  // `node` holds nothing due (it is dead, or done).
  void clear(uint32_t node) { due_.erase(node); }
  bool holds(uint32_t node) const;

  // At `at`: "grant G overdue by X s" for `node`'s oldest grant past due, or "".
  std::string overdue(uint32_t node, double at) const;

  // Once a node has measured its first grant as `measured_s`: the k-th outstanding grant (from
  // 0) of each of `nodes` is due at most now + slack + (k + 1) unequal_first measured_s. Returns
  // whether any due time moved. A node that holds its first grants without answering them, or
  // answers sixteen times slower, is caught then, not after first_grant_s.
  bool tighten(const std::vector<uint32_t>& nodes, double now, double measured_s);

 private:
  DeadlineRules rules_;
  std::map<uint32_t, std::vector<std::pair<uint64_t, double>>> due_;
};

}  // namespace sirad::cluster
