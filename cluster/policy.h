// sirad: the coordinator's decisions as plain state, free of sockets and clocks (DESIGN.md
// section 2): who gets which grant when (async depth, the sync barrier, grant sizes aligned to
// the sampling plan), what a report changes (ledger, aggregate, the exchange it is answered
// with), when the run closes and ends, and its error estimate. The ZeroMQ coordinator
// (coordinator.cpp) and the virtual-time cluster (emulate.cpp) both drive this one class, so
// an emulated timeline is decided exactly as a real run would be. It is the solve's phase
// (DESIGN.md section 2), shaped as the image's (cluster/image_phase.h): next_work gives what to
// send, take_result takes a node's result, and the due times of grants are grant_time_bound's.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "cluster/exchange.h"
#include "cluster/plausibility.h"
#include "cluster/profile.h"
#include "engine/bundle.h"
#include "model/model.h"
#include "scene/mesh.h"
#include "solver/solver.h"

namespace sirad::cluster {

// The exchange setting --exchange-every auto chose, and from what.
struct ExchangeSetting {
  uint32_t exchange_every = 0;
  double fraction = 1.0;
  std::string why;  // one line: the model's inputs and prediction, or why the model was not used
};

// When a run closes before its budget, on a cluster (Policy::check_close) and on one node
// (run_single) alike: at the time limit, else once an error estimate (< 0: none yet) is at or
// below the target. Returns why ("time limit", "target error (E <= T)"), or "" to go on.
struct CloseRule {
  double time_limit_s = 0;  // 0: none
  double target_error = 0;  // 0: none
  std::string check(double elapsed_s, double estimate) const;
  bool wants_estimate() const { return target_error > 0; }
};

struct PolicyConfig {
  uint64_t bundles = 0;
  uint32_t exchange_every = 0;  // I (0: states only at the end; kExchangeAuto: choose() decides)
  double fraction = 1.0;        // S
  Topology topology = Topology::star;
  Mode mode = Mode::async;
  UpdateRule rule = UpdateRule::chain;  // chain: the nodes' chains are independent (error estimate)
  uint32_t min_nodes = 1;       // ready nodes before the first grant
  uint64_t grant_unit = 1;      // grants are whole multiples of it (grant_unit())
  double time_limit_s = 0;      // 0: none; else no grants after this long
  double target_error = 0;      // 0: none; else close once error_estimate() is at or below it
  // Grants sized to each node's speed (grant_size(n)): on unequal nodes every grant takes about
  // the same time, so sync barriers do not wait on the slow and a closing run is held up less
  // by a slow node's grant. Off: every grant has the same bundle count.
  bool balance = true;
  // Bundles per batch of a node's states in the plausibility tests (chain_memory).
  uint64_t batch_bundles = 1;
  // With exchange_every = kExchangeAuto: called once, when the first grants are about to go
  // out, with the ready nodes' indices; the driver measures what the model needs (auto_exchange).
  std::function<ExchangeSetting(const std::vector<uint32_t>& ready)> choose;
};

// What --exchange-every auto knows of one ready node: its seconds per bundle (slowdown
// included) and the seconds its link takes to carry the whole state up and back down
// (exchange_seconds).
struct NodeCost {
  double t_iteration = 0;
  double t_transfer = 0;
};

// --exchange-every auto for `nodes` sharing `bundles` (or, with a time limit, that
// time: then exchanging costs bundles not done).
// Average rule: the paper's model (model/model.h choose_exchange) picks I and S, with T_i the
// nodes' median bundle time and T_e such that an exchange costs P S T_e (eq. 1) =
// max(S e, P S c): the nodes' links carry their states side by side (e: the slowest transfer;
// 0 in async mode, where a queued grant hides it), the coordinator's link (c: its time per
// node's state, coordinator_seconds; 0 for a link that is no bottleneck) one after another.
// Chain rule: an exchange never changes a node's chain, so the paper's gain from combining does
// not exist; reports only feed the coordinator's estimate, its error estimate and the stopping
// rules, and cost transfers. Then S = 1 (a stale chunk makes the error estimate pessimistic and
// the run stop late: measured in bench/paper/REPORT.md) and I is the shortest period at which
// every node's link keeps up: max_p e_p / t_p in async mode (a queued grant runs while the
// report travels), max_p 10 e_p / t_p in sync (the barrier waits for it: under a tenth), and
// the coordinator's too: c sum_p 1 / t_p (10 times that in sync), at most bundles / (8 P). Short grants end a run promptly at its target. Fractions stay at or
// above 1 / chunks.
ExchangeSetting auto_exchange(UpdateRule rule, const model::Scene& scene, const std::vector<NodeCost>& nodes, Mode mode,
                              uint64_t bundles, uint32_t chunks, double time_limit_s = 0, double coordinator_transfer = 0);

// Seconds for one node's link to carry the whole state (24 bytes per patch) up and the others'
// back down, with the latency both ways; an unshaped LAN (1 Gbit/s, 0.1 ms) without a profile.
double exchange_seconds(std::size_t patches, const emulation::LinkSpec* link);
// Seconds of the coordinator's own link per node's state in an exchange: one state in while
// another goes out (the link is full duplex, so the P states in and the P answers out overlap),
// the slower direction's transfer and one latency.
double coordinator_seconds(std::size_t patches, const emulation::LinkSpec& link);

// Grants must be whole multiples of: the interleave G under stratified directions (a node's
// chain runs same-sequence bundles >= G steps apart even across grants, engine/bundle.cpp), and
// 1 / X when that is a whole number k of steps sharing one shot (solver/solver.h shots_of_step),
// so each shot stays on one node and the nodes' chains stay independent.
uint64_t grant_unit(const PatchMesh& mesh, Directions directions, double shots_per_bundle);

// The error estimate's patch weights: the area of non-emitting patches (emitters are mostly E,
// known exactly); every patch's area where all of them emit (the furnace).
std::vector<double> error_weights(const PatchMesh& mesh);

struct NodeState {
  bool ready = false, stopped = false, final_in = false, dead = false;
  // Sent an impossible state (quarantine()): dead too, its data and its bundles dropped.
  bool quarantined = false;
  std::string why;              // why it was quarantined
  std::vector<uint64_t> grants;  // outstanding grant ids, oldest first (at most 2)
  uint32_t rotation = 0;        // grants given with report chunks (the rotation of S)
  uint32_t exchanges = 0;
  uint64_t bundles = 0;
  double suspicion = 0;         // the largest plausibility score of its states taken (Plausibility)
  double error = -1;            // its last reported error estimate (<= 0: none)
  uint64_t error_bundles = 0;   // the bundles it had done then
  // "quarantined" | "dead" | "done" | "joining" | "working" | "waiting" (Status::Node::state)
  const char* state() const;
};

struct GrantOrder {
  uint32_t node = 0;
  uint64_t id = 0;
  std::vector<Range> ranges;
  std::vector<uint32_t> report_chunks;  // the chunks its REPORT carries (empty: no exchange)
};

// What the policy wants sent now: grants, then STOPs (the node has no more work: FINAL next).
struct Orders {
  std::vector<GrantOrder> grants;
  std::vector<uint32_t> stops;
};

// A node's state of one chunk: 3 doubles (rgb) per patch, and its bundle count.
struct ChunkState {
  uint32_t chunk = 0;
  std::vector<double> sum;
  uint64_t count = 0;
};

// The answer to a REPORT that carried chunks: the others' data for each (Aggregate::others).
struct Exchange {
  uint32_t exchange = 0;  // the node's exchange number
  std::vector<uint32_t> chunks;
  std::vector<Aggregate::Part> parts;
};

// What a checkpoint keeps of a node (cluster/checkpoint.h): its counters, its last state of
// every chunk, and the ledger's record of the bundles it ran.
struct NodeRecord {
  NodeState state;
  std::vector<Aggregate::Part> parts;  // per chunk
  std::vector<Range> done;
};

// The policy's state between messages, all a resumed run needs (Policy::restore).
struct PolicySnapshot {
  std::vector<NodeRecord> nodes;
  uint32_t exchange_every = 0;  // as in force (what auto chose)
  double fraction = 1.0;
  std::string exchange_why;
  uint32_t exchanges = 0;
  uint64_t reports = 0;
  bool closing = false;
  std::string ended_by;
};

class Policy {
 public:
  // `starts`: chunk_starts of the mesh; `weight`: error_weights of the mesh; `bounds`:
  // chunk_bounds of the mesh (empty: no scene bound, chunks' patches weigh the same).
  Policy(const PolicyConfig& config, std::vector<uint32_t> starts, std::vector<double> weight, ChunkBounds bounds = {});

  PolicySnapshot snapshot() const;
  // Continues a checkpointed run (before any join): every node of `s` is in again with its
  // counters, states and done bundles, but dead (its process belongs to the coordinator that
  // stopped; it rejoins as a new node), its grants back in the budget. Throws sirad::Error for
  // a snapshot that does not fit this run (chunk sizes, bundle ranges).
  void restore(const PolicySnapshot& s);

  // A new node (not ready yet); its index. A run keeps at most kMaxNodeEntries entries: beyond
  // that a new node takes the index of the oldest departed entry that holds nothing (dead or
  // quarantined, no state in the aggregate, no bundle in the ledger: a node that joined and
  // left, or cycled HELLO and READY), which is forgotten. Throws sirad::Error when every entry
  // holds something.
  uint32_t join();
  static constexpr uint32_t kMaxNodeEntries = 4096;
  uint32_t nodes() const { return static_cast<uint32_t>(nodes_.size()); }
  const NodeState& node(uint32_t n) const { return nodes_.at(n); }
  void ready(uint32_t n);  // throws sirad::Error for a second READY
  // Declares node n dead: its outstanding grant goes back to the budget. Returns how many
  // bundles went back. Call next_work() next (a sync barrier may have waited on it).
  uint64_t dead(uint32_t n);
  // The same for a node gone while it held its grants (silent, unreachable, past due: not one
  // that left on purpose or said HELLO again), known as `who` (its CURVE key, else its
  // address): each bundle it held counts a loss by `who` (Ledger::lose). Bundles lost by
  // kMaxBundleLosses identities may crash whoever runs them, so the run closes then (close():
  // no more grants; it ends with the bundles done, its ended_by naming them) rather than
  // handing them to node after node.
  uint64_t lost(uint32_t n, const std::string& who);
  static constexpr uint32_t kMaxBundleLosses = 3;
  // What a run closed by lost bundles says (its ended_by, the drivers' error).
  static std::string lost_reason(const Range& bundles);
  // Quarantines node n for sending what no honest node can (a non-finite or absurd value, a
  // count beyond its bundles or going backwards, bundles it was not granted): dead, its data
  // dropped from the aggregate, and every index granted to it, done or not, back in the budget,
  // so the run still ends with its full count of accepted bundles. Returns how many bundles it
  // had done. Call next_work() next.
  uint64_t quarantine(uint32_t n, const std::string& why);

  // Gives grants and STOPs. Async: every live ready node holds two grants, the one it runs and
  // one queued behind it, so it never waits for the REPORT -> GRANT round trip; near the end of
  // the budget (less than two grants per node left) only one, so no node queues work a faster
  // one could take. Sync: one each, given only when no node holds one (the exchange barrier).
  Orders next_work();

  // Node n's REPORT for grant `grant_id` (which must be its oldest): the done ranges go into
  // the ledger, the chunks into the aggregate. Returns the exchange to answer with (none when
  // the report carried no chunks). Throws sirad::Error when refused: a report for a grant the
  // node does not hold changes nothing; one whose data (or error estimate, or done ranges) no
  // honest node sends, or whose chunks are implausible (cluster/plausibility.h), quarantines
  // the node. Call next_work() next, always.
  std::optional<Exchange> take_result(uint32_t n, uint64_t grant_id, const std::vector<Range>& done,
                                 std::vector<ChunkState> chunks, double error_estimate);
  // Node n's FINAL (after its STOP): its end states (impossible ones quarantine it, as above).
  void final_state(uint32_t n, std::vector<ChunkState> chunks);

  // The time limit (elapsed_s on the driver's clock) or the target error closes the run: no
  // more grants, the outstanding ones finish. True when it closed now; call next_work() next.
  bool check_close(double elapsed_s);
  // Closes the run now, ended by `why` (an interrupt), as check_close would. False when it was
  // closing or finished already.
  bool close(const std::string& why);
  bool closing() const { return closing_; }
  const std::string& ended_by() const { return ended_by_; }
  // Every bundle done, or the run closed and every outstanding grant is in.
  bool ending() const;
  // Ending, and the FINAL of every live ready node is in.
  bool done() const;

  // The run's relative error estimate (see the .cpp), or < 0 while there is none.
  double error_estimate() const;
  // The count-weighted estimate per patch.
  std::vector<glm::vec3> radiosity() const;

  // Bundles per grant: I (or, exchanging only at the end, bundles / (8 P)), in whole grant
  // units. With `balance` and node n's bundle time known, times f = the fastest ready node's
  // bundle time over n's, rounded up to a power of two (nodes within 2x of the fastest get
  // exactly I: measured times are noisy) and at least 1/16: each grant then takes about I of
  // the fastest node's bundles (or one grant unit, if that is longer). No grant grows: a long
  // one would hold up a run that closes at its target.
  // Near the end of the budget of an async run a grant is also at most half of node n's share
  // (by speed) of the bundles not granted yet (guided self-scheduling), down to one bundle: the
  // nodes run out of work together (see the .cpp).
  // Without exchanges (I = 0) a grant is K / (8 P), and at most kTargetReportBundles when the
  // run ends at a target error (its estimate comes with each report) or a time limit (no grant
  // of K / (8 P) bundles outlasting it by hours).
  uint64_t grant_size() const;
  static constexpr uint64_t kTargetReportBundles = 64;
  uint64_t grant_size(uint32_t n) const;
  // Node n's seconds per bundle, as its driver measures it (READY, then busy / bundles of its
  // reports); <= 0 or non-finite: unknown.
  void set_bundle_time(uint32_t n, double seconds);
  // The longest node n may honestly take for a grant of `bundles`: 8 times them at its bundle
  // time (as measured, else `claimed_s`, what its READY said; unknown: 1 s), that time taken
  // at most 16 times the fastest ready node's measured one (balanced grants assume no larger
  // spread) and at most 10 s. The driver adds its liveness window, and declares a node whose
  // grant is out longer than that dead (dead(): the grant goes back to the budget), so a node
  // that heartbeats but never reports cannot stall the run.
  double grant_time_bound(uint32_t n, uint64_t bundles, double claimed_s) const;
  const Ledger& ledger() const { return ledger_; }
  const Aggregate& aggregate() const { return aggregate_; }
  const std::vector<uint32_t>& starts() const { return starts_; }
  uint32_t exchanges() const { return exchanges_; }
  uint64_t reports() const { return reports_; }
  const PolicyConfig& config() const { return config_; }
  // The exchange setting in force (after auto chose it, what it chose and why).
  uint32_t exchange_every() const { return config_.exchange_every; }
  double fraction() const { return config_.fraction; }
  const std::string& exchange_why() const { return exchange_why_; }

 private:
  uint64_t balanced_size(uint32_t n) const;  // grant_size(n) before the end of the budget
  double speed_share(uint32_t n) const;      // node n's part of the live ready nodes' speed
  // Every chunk checked (Aggregate::check, its count within the node's bundles, Plausibility),
  // then all taken, or none and the node quarantined.
  void take_chunks(uint32_t n, std::vector<ChunkState>& chunks);
  [[noreturn]] void quarantine_and_fail(uint32_t n, const std::string& why);

  PolicyConfig config_;
  std::vector<uint32_t> starts_;
  std::vector<double> weight_;
  Ledger ledger_;
  Aggregate aggregate_;
  Plausibility plausible_;
  std::vector<NodeState> nodes_;
  std::vector<double> bundle_time_;  // per node (0: unknown)
  uint64_t grants_ = 0, reports_ = 0, last_error_check_ = 0;
  uint32_t exchanges_ = 0;
  bool started_ = false, closing_ = false;
  std::string ended_by_;
  std::string exchange_why_;
};

}  // namespace sirad::cluster
