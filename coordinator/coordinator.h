// sirad: the coordinator (proto/PROTOCOL.md): serves one run on a ROUTER socket, handing out
// grants from the bundle budget, answering reports with the exchange the policy says, and
// collecting the final states into the count-weighted estimate. The bookkeeping is
// coordinator/exchange.h; this file only moves messages.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <zmq.hpp>

#include "coordinator/exchange.h"
#include "coordinator/policy.h"
#include "coordinator/profile.h"
#include "coordinator/status.h"
#include "core/mesh.h"
#include "core/output.h"
#include "core/scene.h"
#include "core/solver.h"
#include "proto/codec.h"

namespace sirad::cluster {

struct RunConfig {
  Scene scene;            // sent to the nodes, which mesh it with `mesh_options`
  MeshOptions mesh_options;
  uint64_t bundles = 1000;
  uint64_t seed = 1;
  int grid = 0;           // the run's grid (0: auto from the mesh)
  UpdateRule rule = UpdateRule::chain;
  int burn_in = -1;
  Directions directions = Directions::random;  // stratified: chain rule only
  bool control_variate = true;  // the transport's control variate (core/solver.h SolverOptions)
  double shots_per_bundle = 0;  // first shot: shots rendered per bundle (0: off)
  int shot_resolution = 0;      // hemicube side (0: auto)
  uint32_t exchange_every = 0;  // I; 0: states only at the end
  double fraction = 1.0;        // S
  Topology topology = Topology::star;
  Mode mode = Mode::async;
  uint32_t chunks = 16;
  bool balance = true;          // grants sized to each node's speed (PolicyConfig::balance)
  uint32_t min_nodes = 1;       // nodes ready before the first grant
  double timeout_s = 0;         // 0: none; else the run fails if it takes longer
  double time_limit_s = 0;      // 0: none; else no grants after this long: the run ends early
  double target_error = 0;      // 0: none; else the run ends early once the error estimate
                                // (Status::error_estimate) is at or below it
  uint32_t heartbeat_ms = 1000; // HEARTBEAT interval of both sides (PROTOCOL.md section 4)
  uint32_t liveness = 3;        // a peer silent this many intervals is dead
  std::optional<emulation::Profile> profile;  // --profile: network and speed emulation
  bool emulate_bandwidth = true;  // false: the network itself limits bandwidth (tc tbf in the
                                  // namespace cluster); the profile's other settings still apply
  const std::atomic<bool>* abort = nullptr;  // set: the run fails at once (a local node died)
  bool strict = false;          // a node's ERROR ends the run (the embedded default: its nodes
                                // are this process's own threads)
  // The checkpoint (coordinator/checkpoint.h): written atomically to `checkpoint` every
  // checkpoint_every_s and when `interrupt` is set ("" : none).
  std::string checkpoint;
  double checkpoint_every_s = 10;
  const std::atomic<bool>* interrupt = nullptr;  // set (SIGTERM): checkpoint, then the run throws
  // set (SIGINT on `sirad render --nodes`): the run closes as at a time limit, ended by
  // "interrupted": no more grants, the outstanding ones finish, the result is what was done.
  const std::atomic<bool>* close = nullptr;
  // Continue this checkpointed run (read_checkpoint; apply_checkpoint gave `config` its
  // settings): its nodes' states and the ledger as accepted, the rest of the budget to run.
  const wire::Checkpoint* resume = nullptr;
  std::function<void(uint64_t done, uint64_t total)> progress;  // called as bundles complete
  std::function<void(const Status&)> status;  // called every status_every_s, and at the end
  double status_every_s = 1.0;
};

struct NodeReport {
  std::string name;
  uint64_t bundles = 0;
  uint32_t exchanges = 0;
  double busy_s = 0, idle_s = 0;  // as the node last reported them
  bool dead = false;              // declared dead (silent for `liveness` heartbeats)
  std::string quarantined;        // why it was quarantined (empty: it was not)
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
  int grid = 0;            // the run's grid (config.grid, or the auto grid of the mesh)
  uint64_t bundles = 0;    // bundles done (config.bundles unless a time limit or target ended it)
  std::string ended_by;    // "budget", "time limit", "target error ..." or "interrupted"
  double error_estimate = -1;  // the spread estimate at the end (Policy::error_estimate; < 0: none)
  uint32_t exchange_every = 0;  // the period and fraction the run used (what auto chose)
  double fraction = 1.0;
  std::string exchange_why;     // with auto: how it chose
};

// The settings a wire Run carries (what the coordinator sends in WELCOME and keeps in its
// checkpoint) into `config`: bundles, seed, grid, rule, burn-in, directions, control variate,
// first shot, exchange period and fraction, topology, mode, chunks, meshing. Throws
// sirad::Error for a rule, directions, topology or mode it does not know.
void apply_run(RunConfig& config, const wire::Run& run);

// The solver options of node `index` in a run of `config` on `mesh`: a node from its WELCOME
// (apply_run), the virtual-time cluster from its own config.
SolverOptions node_solver_options(const RunConfig& config, const PatchMesh& mesh, uint32_t index);

// The policy's settings for a run of `config` on `mesh` (checks the sampling settings; the
// chooser of --exchange-every auto is the driver's to add).
PolicyConfig policy_config(const RunConfig& config, const PatchMesh& mesh, uint32_t min_nodes);

// --exchange-every auto for a run of `config`: auto_exchange (policy.h) with the scene fitted
// on this machine when the model needs it (the average rule; a fit that fails falls back to
// the chain rule's choice and says so).
ExchangeSetting auto_setting(const RunConfig& config, const PatchMesh& mesh, const std::vector<NodeCost>& nodes,
                             uint32_t chunks, BundleEngine* engine = nullptr);

// The EXR header attributes of a cluster run (DESIGN.md section 4: scene hash, bundles, nodes,
// R, I, S, seed, and the topology and mode), `scene` naming it as the user did.
Attributes run_attributes(const RunConfig& config, const RunResult& result, const PatchMesh& mesh,
                          const std::string& scene);

// "exchange traffic: E exchanges, X B up, Y B down (x B up, y B down per exchange); final
// states Z B" (bulk bytes: 24 per patch of each chunk sent).
std::string traffic_line(const RunResult& result);

// The ledger as CSV: "node,name,first,last", a row per range (written by --ledger).
std::string ledger_csv(const RunResult& result);

// One line per node: "node NAME: B bundles, E exchanges, busy Xs, idle Ys[, dead | , quarantined: WHY]".
std::string node_lines(const RunResult& result);

// Serves one run of `mesh` (meshed from config.scene with config.mesh_options) until every
// bundle is done and every node's final state is in (or continues config.resume; its scene hash
// and chunks must match `mesh`). Malformed or unexpected messages are
// refused and logged; the run goes on. A node silent for `liveness` heartbeat intervals is
// declared dead: its outstanding grant returns to the budget and its last accepted state stays
// in the estimate. Throws sirad::Error on the timeout, and when `interrupt` is set (after the
// checkpoint, if any, is written).
RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh);

}  // namespace sirad::cluster
