// sirad: a run on one node without a cluster: the bundles of the budget in index order on one
// solver, ended by the same rule as a cluster run (CloseRule, cluster/policy.h) with the
// solver's own batch-means estimate in place of the nodes' spread.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "cluster/settings.h"
#include "solver/solver.h"

namespace sirad::cluster {

struct SingleRun {
  uint64_t bundles = 0;            // counted bundles run
  std::string ended_by = "budget";
  double seconds = 0;
};

// Runs bundles 0.. of `s` on `solver` until the budget is done or the run closes: at the time
// limit (wall time), at the target error (checked every 16 bundles once the estimate can be
// trusted: Solver::error_estimate_ready), or, after at least one bundle, when `close` is set
// (ended by close_why()). `progress` is called after every bundle with the bundles done and
// the seconds of the run. Its seconds start at `setup_s` (the solver's construction, which
// ran its burn-in), as a cluster run's clock starts before its nodes are set up.
SingleRun run_single(Solver& solver, const RunSettings& s, const std::atomic<bool>* close,
                     const std::function<std::string()>& close_why,
                     const std::function<void(uint64_t done, double seconds)>& progress = {}, double setup_s = 0);

}  // namespace sirad::cluster
