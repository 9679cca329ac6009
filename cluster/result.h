// sirad: what a cluster run reports (the real coordinator's and the virtual-time cluster's),
// and the lines its drivers print of it.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "cluster/exchange.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "render/gather.h"

namespace sirad::cluster {

struct NodeReport {
  std::string name;
  uint64_t bundles = 0;
  uint32_t exchanges = 0;
  double busy_s = 0, idle_s = 0;  // as the node last reported them
  bool dead = false;              // declared dead (silent for `liveness` heartbeats)
  std::string quarantined;        // why it was quarantined (empty: it was not)
  bool before_resume = false;     // a node of the run before it was resumed from a checkpoint
  uint64_t tiles = 0;             // tiles of the run's image it rendered
};

// One range of the ledger's record: node `node` (its index in the run, `name`) ran [first, last).
struct LedgerEntry {
  uint32_t node = 0;
  std::string name;
  Range range;
};

struct RunResult {
  std::vector<glm::vec3> radiosity;  // the count-weighted estimate per patch
  std::vector<NodeReport> nodes;
  std::vector<LedgerEntry> ledger;   // who ran which accepted bundles, by node then index
  uint64_t exchange_bytes_in = 0, exchange_bytes_out = 0;  // REPORT and UPDATE bulk
  uint64_t final_bytes = 0;                                // FINAL bulk (the end states)
  uint32_t exchanges = 0;
  uint64_t crossings = 0;  // line-patch crossings of all counted bundles
  // A run resumed from a checkpoint: the bundles and crossings done before (counted above too).
  uint64_t bundles_before = 0, crossings_before = 0;
  double seconds = 0;      // the run's time, from its start to its last FINAL (emulated: virtual)
  int grid = 0;            // the run's grid (as set, or the auto grid of the mesh)
  uint64_t bundles = 0;    // bundles done (the budget unless a time limit or target ended it)
  std::string ended_by;    // "budget", "time limit", "target error ..." or "interrupted"
  double error_estimate = -1;  // the spread estimate at the end (Policy::error_estimate; < 0: none)
  uint32_t exchange_every = 0;  // the period and fraction the run used (what auto chose)
  double fraction = 1.0;
  std::string exchange_why;     // with auto: how it chose
  // The final gather's image, when the run rendered one (RunConfig::final_gather), its time
  // (from the last FINAL), its tiles, and those the coordinator rendered itself (no node left).
  std::optional<GatherPasses> image;
  // Why the image was not made (empty: it was, or none was asked): a tile that crashed every
  // node it went to, the run's time limit reached during the image. The solution stays good
  // (write_results keeps it).
  std::string image_error;
  // Bundles lost with Policy::kMaxBundleLosses nodes (they may crash whoever runs them): the run
  // closed with the bundles done. Its drivers write the outputs and then fail.
  std::optional<Range> bundles_lost;
  double image_seconds = 0;
  uint64_t image_tiles = 0, tiles_here = 0;
};

class Policy;
// How a cluster run came out, for run_attributes (settings.h).
RunOutcome outcome_of(const RunResult& result);
// What the policy of a finished run knows of it: the estimate, exchanges, bundles, how it
// ended, its error estimate and the exchange setting in force; `grid` as run. The driver adds
// its nodes, ledger, traffic and crossings.
RunResult policy_result(const Policy& policy, int grid);
// What the policy of a run of `s` knows of it now, as a Status: bundles, the error estimate,
// the exchange setting in force, and a node per policy index with its state, bundles,
// exchanges and why; `last`: the run has ended (ended_by says how). The driver adds the
// elapsed time, the traffic and what only it knows of each node (name, device, times, rate).
Status policy_status(const Policy& policy, const RunSettings& s, bool last);

// "exchange traffic: E exchanges, X B up, Y B down (x B up, y B down per exchange); final
// states Z B" (bulk bytes: 24 per patch of each chunk sent).
std::string traffic_line(const RunResult& result);

// The ledger as CSV: "node,name,first,last", a row per range (written by --ledger).
std::string ledger_csv(const RunResult& result);

// One line per node: "node NAME: B bundles, E exchanges, busy Xs, idle Ys[, T tiles][, dead | , quarantined: WHY]".
std::string node_lines(const RunResult& result);

// The last line of every run's summary: "patches N, bundles B, grid G[, nodes P], T s, R
// bundles/s, C line crossings/s" and `extra` (", error estimate ..."), for one node (nodes 0)
// and for a cluster alike.
std::string summary_line(std::size_t patches, uint64_t bundles, int grid, uint32_t nodes, double seconds, uint64_t crossings,
                         const std::string& extra = "");

// A cluster run's summary as every driver prints it: node_lines, traffic_line, the image's
// line when it rendered one ("image: T tiles in S s[, H rendered by the coordinator]"), then
// summary_line with the run's nodes and `seconds`.
std::string cluster_summary(const RunResult& result, std::size_t patches, double seconds);

}  // namespace sirad::cluster
