// sirad: a run on one node (see single_node.h).
#include "cluster/single_node.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "cluster/policy.h"

namespace sirad::cluster {

SingleRun run_single(Solver& solver, const RunSettings& s, const std::atomic<bool>* close,
                     const std::function<std::string()>& close_why, const std::function<void(uint64_t, double)>& progress,
                     double setup_s) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto elapsed = [&] { return setup_s + std::chrono::duration<double>(Clock::now() - start).count(); };
  const CloseRule rule{s.time_limit_s, s.target_error};
  SingleRun r;
  for (uint64_t k = 0; k < s.bundles;) {
    const auto count = static_cast<uint32_t>(std::min<uint64_t>(solver.batch(), s.bundles - k));
    solver.step_batch(k, count);
    k += count;
    r.bundles = k;
    if (r.bundles == s.bundles) break;
    if (close && close->load()) {
      r.ended_by = close_why ? close_why() : "interrupted";
      break;
    }
    const double t = elapsed();
    if (progress) progress(r.bundles, t);
    // Every 16 bundles (a batch may step over the multiple itself).
    const bool look = rule.wants_estimate() && r.bundles / 16 != (r.bundles - count) / 16 && solver.error_estimate_ready();
    if (std::string why = rule.check(t, look ? solver.error_estimate() : -1.0); !why.empty()) {
      r.ended_by = std::move(why);
      break;
    }
  }
  if (progress && r.bundles == s.bundles) progress(r.bundles, elapsed());
  r.seconds = elapsed();
  return r;
}

}  // namespace sirad::cluster
