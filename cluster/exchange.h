// sirad: the cluster's bookkeeping as plain state, free of sockets and clocks (DESIGN.md
// section 2): the bundle ledger (every index 0..K-1 granted once, done once), the per-node,
// per-chunk (sum, count) states with the count-weighted global estimate, and the exchange
// schedule (period I, fraction S rotating over chunks, star or ring). The coordinator over
// ZeroMQ, the embedded default and a virtual-clock emulation all drive this same code.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace sirad::cluster {

enum class Topology { star, ring };
enum class Mode { sync, async };
Topology parse_topology(const std::string& s);  // "star" | "ring"; throws sirad::Error
Mode parse_mode(const std::string& s);          // "sync" | "async"; throws sirad::Error
// --exchange-every: a bundle count >= 1, "end" (0: states only at the end of the run), or
// "auto" (kExchangeAuto: the coordinator chooses I and S at the start, policy.h).
inline constexpr uint32_t kExchangeAuto = 0xffffffffu;
uint32_t parse_exchange_every(const std::string& s);
std::string exchange_every_name(uint32_t exchange_every);  // "end", "auto" or the number

// A half-open range of bundle indices [first, last).
struct Range {
  uint64_t first = 0, last = 0;
  uint64_t size() const { return last - first; }
  bool operator==(const Range&) const = default;
};

// The run's bundle budget. Grants come from the lowest indices not yet given out; a grant
// that is abandoned (its node died) goes back and is granted again; an index is done once.
class Ledger {
 public:
  explicit Ledger(uint64_t bundles);
  // Up to `count` indices for `node`, as ranges; empty when the budget is all granted.
  std::vector<Range> grant(uint32_t node, uint64_t count);
  // Index `index` for `node` if it is free (neither granted nor done); false otherwise.
  bool grant_index(uint32_t node, uint64_t index);
  // `node` finished `r`: every index must be granted to it and not yet done, or this throws
  // sirad::Error naming the first offending index (nothing is counted twice).
  void done(uint32_t node, Range r);
  // Everything granted to `node` and not done returns to the budget.
  void abandon(uint32_t node);
  // The same for a node that died while it held them (gone, or past its grant's due time):
  // each of those indices counts a loss by `who` (the node's identity: a peer that joins again
  // and again counts once). A bundle that crashes whoever runs it (a kernel fault on one
  // direction) is lost with every node it goes to, since the lowest free indices are granted
  // first; poisoned() names the first range lost by `times` identities or more, merged.
  void lose(uint32_t node, const std::string& who);
  std::optional<Range> poisoned(uint32_t times) const;
  // Everything granted to `node`, done or not, returns to the budget (a quarantined node: its
  // data are dropped, so its bundles must be run again). Returns how many were done.
  uint64_t revoke(uint32_t node);
  // The indices `node` has done, merged and sorted (the ledger's record: who ran what).
  std::vector<Range> done_by(uint32_t node) const;
  // A ledger from its record alone (a resumed run: nothing is granted, everything not done is
  // free). Throws sirad::Error for ranges that are empty, beyond the budget or overlap.
  static Ledger from_record(uint64_t bundles, const std::map<uint32_t, std::vector<Range>>& done);
  uint64_t bundles() const { return bundles_; }
  uint64_t done_count() const { return done_count_; }
  uint64_t outstanding(uint32_t node) const;
  uint64_t available() const;  // indices not granted to anyone
  bool finished() const { return done_count_ == bundles_; }

 private:
  uint64_t bundles_;
  std::vector<Range> free_;                           // sorted, disjoint
  std::map<uint32_t, std::vector<Range>> granted_;    // per node, not yet done
  std::map<uint32_t, std::vector<Range>> done_;       // per node, done (unmerged)
  uint64_t done_count_ = 0;
  // Indices lost at least once (lose()): disjoint ranges, first -> their last and who lost
  // them (distinct, at most kLossesKept). At most two entries more per range a loss returns:
  // bounded by the node entries a run keeps.
  struct Lost {
    uint64_t last = 0;
    std::vector<std::string> who;
  };
  static constexpr std::size_t kLossesKept = 8;
  std::map<uint64_t, Lost> losses_;
};

// Contiguous chunks of patches: chunk c is [starts[c], starts[c+1]), starts.back() = patches.
std::vector<uint32_t> chunk_starts(uint32_t patches, uint32_t chunks);

// The chunks a node reports at its e-th exchange: n = ceil(S * C) of them, rotating
// (e * n + i) mod C, so every chunk goes out over time; S = 1 gives all.
std::vector<uint32_t> exchange_chunks(uint32_t exchange, double fraction, uint32_t chunks);

// The last (sum, count) received from every node for every chunk, and what follows from them.
class Aggregate {
 public:
  Aggregate(std::vector<uint32_t> starts, uint32_t nodes);
  uint32_t chunks() const { return static_cast<uint32_t>(starts_.size() - 1); }
  uint32_t chunk_size(uint32_t c) const { return starts_[c + 1] - starts_[c]; }
  uint32_t nodes() const { return static_cast<uint32_t>(state_.size()); }
  void add_node();

  // A node's new state of chunk c: 3 doubles (rgb) per patch of the chunk, and its count.
  // Refused (sirad::Error, state unchanged) for a wrong size, a count that goes backwards, or a
  // non-finite or negative value.
  void set(uint32_t node, uint32_t chunk, std::vector<double> sum, uint64_t count);
  // What set() checks, without setting: throws sirad::Error naming the first problem.
  void check(uint32_t node, uint32_t chunk, const std::vector<double>& sum, uint64_t count) const;
  // Drops everything node has sent (a quarantined node): its sums and counts become zero.
  void clear(uint32_t node);
  // Whether node holds no state with a count (never reported one, or cleared).
  bool holds_nothing(uint32_t node) const;

  struct Part {
    std::vector<double> sum;  // 3 per patch of the chunk
    uint64_t count = 0;
  };
  // Node `node`'s last state of chunk c (zeros with count 0 before it sent one: a node's parts
  // are allocated at its first state, so nodes that join and never report cost no chunk memory).
  // Each node's state is held as its mean in single precision, 12 bytes per patch (64 nodes at
  // a million patches: 768 MB, where doubles of the sums took 1.5 GB): the sum comes back as
  // mean x count, within 2^-24 of the sum sent (check() bounds every mean by the largest float;
  // the estimates themselves are made from floats). A state that went through state() and
  // set() again (a checkpoint) is held bit for bit as before: float -> double x count (exact
  // below 2^29 bundles) / count is the same float.
  Part state(uint32_t node, uint32_t chunk) const;
  // What `node` receives for chunk c: star, the sum over all other nodes; ring, node + 1's.
  Part others(uint32_t node, uint32_t chunk, Topology topology) const;
  // The count-weighted global estimate of chunk c: sum of sums / sum of counts (zeros where no
  // node has reported).
  std::vector<double> estimate(uint32_t chunk) const;
  uint64_t count(uint32_t chunk) const;

  // The relative error of the global estimate from the spread of the nodes' own estimates:
  // with independent chains (the chain rule: an exchange never changes a node's chain) node p's
  // mean x_p of m_p bundles has variance s^2 / m_p, so per patch and channel
  //     s^2 = sum_p m_p (x_p - G)^2 / (P - 1),   Var(G) = s^2 / sum_p m_p,
  // over the P nodes holding a state of the chunk. Returns sqrt(sum_j w_j Var_j / sum_j w_j G_j^2)
  // over patches (w: one weight per patch, e.g. the area of non-emitting patches, 0 to leave a
  // patch out; channels averaged), or -1 where no chunk has two nodes' states. Under the
  // average rule with exchanges the nodes are correlated and this underestimates.
  double spread_error(const std::vector<double>& weight) const;

  // The relative error of the global estimate from the nodes' own error estimates (chain rule:
  // independent chains). Node p reported relative error e_p for its estimate after n_p bundles
  // (error[p], bundles[p]); the aggregate holds its chunk c with count m_pc <= n_p (a chunk
  // sent earlier, or data refused since), whose error is then e_p sqrt(n_p / m_pc). The
  // chunk's count-weighted mean has relative variance
  //     V_c = sum_p (m_pc / M_c)^2 e_p^2 n_p / m_pc = sum_p m_pc n_p e_p^2 / M_c^2,
  // and the run's estimate is sqrt(sum_c W_c V_c / sum_c W_c), W_c the chunk's total weight
  // (weight: one per patch, 0 to leave a patch out). Returns -1 when a node holding a chunk
  // has no estimate (e_p <= 0) or nothing is held.
  double combined_error(const std::vector<double>& error, const std::vector<uint64_t>& bundles,
                        const std::vector<double>& weight) const;

 private:
  struct Held {
    std::vector<float> mean;  // 3 per patch of the chunk; empty: zeros
    uint64_t count = 0;
    double sum(std::size_t i) const { return static_cast<double>(mean[i]) * static_cast<double>(count); }
  };
  const Held* held(uint32_t node, uint32_t chunk) const;  // nullptr: zeros
  Part zeros(uint32_t chunk) const;                      // chunk c's values, all 0, count 0
  std::vector<uint32_t> starts_;
  std::vector<std::vector<Held>> state_;  // [node][chunk]; empty until the node's first state
};

}  // namespace sirad::cluster
