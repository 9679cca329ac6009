// sirad: what an honest node's state of a chunk can be (PROTOCOL.md section 5, "Implausible
// states"), as plain state free of sockets and clocks. The policy asks it about every chunk a
// node sends and quarantines the node on a no. Values no node can send at all (non-finite,
// beyond count x FLT_MAX) are Aggregate::check's; this is about values that are possible but
// not plausible: a node that scales its sums, zeroes them, or adds a bias.
//
// The statistic. A node's state of chunk c is (S, m): per patch j the sum of its m per-bundle
// estimates. Each test looks at the chunk's area-weighted mean radiosity, per channel,
//     y = sum_j a_j S_j / m,    a_j = A_j / (the chunk's area),
// a sum over every line that crossed the chunk in each bundle, so close to Gaussian where one
// small patch's estimate is not.
//
// Its noise, from the node's own data. The states a node sends one after another differ by
// the bundles it ran in between: (S' - S) / (m' - m) is the mean of those bundles. Increments
// are merged into batches of at least `batch_bundles` (longer than the chain's memory, so
// batches are nearly independent: chain_memory below); like the nodes' own batch means
// (solver/error_estimate.h) at most kSlots are kept, neighbours merging and the batch length
// doubling when they are full. y's variance is the delete-a-batch jackknife's,
//     Var(y) = (k - 1) / k sum_i (y_(-i) - mean_i y_(-i))^2,   y_(-i) = (S - S_i) / (m - n_i)
// (batch i: n_i bundles summing to S_i): for batches of equal size it is the spread of the
// batch means over k, and whatever the sizes it measures what each batch does to y, so one
// rare large estimate (a small chunk hit by one line, a small bright lamp found by a line)
// widens the node's own standard error by as much as it moves y: alone it stays within about
// one standard error. v = m Var(y) is the chain's variance per bundle. The bundles since the
// last whole batch count as one more batch in every test.
//
// The tests, each needing kMinBatches batches of a variance it uses (below):
//  1. The scene's bound (every rule). Radiosity B = E + rho F B with the rows of F summing to
//     at most 1, so per channel B_j <= E_j + rho_j Bmax with Bmax <= max(Emax / (1 - rho_max),
//     Emax + rho_max Bg) (Bg: the background; no bound where rho_max >= 1), and B_j >= E_j. Both
//     hold for a chunk's area-weighted mean (ChunkBounds). A node whose y is beyond them by more
//     than kZ of its own standard errors plus kFloor of the bound is quarantined.
//  2. The others (chain rule only: independent chains, so each node's y is an unbiased
//     estimate of the same value with variance v / m; the average rule couples the nodes and
//     biases them by their counts). With at least two other nodes of kMinBatches batches (the
//     references), node p's y is compared with the median of theirs and its own:
//         |y_p - med| <= kZ sqrt(max(v_ref / m_p, Var(y_p)) + v_ref / m_min) + kFloor |med|,
//     v_ref the upper median of the references' v (a lying reference cannot shrink it), m_min
//     their least count; p's own variance widens its test (its rare large estimates), and a
//     liar's made-up calm cannot narrow it below the references'. p itself is compared only
//     once it has kMinBatches batches too: a young chain (a node that joined late) is noisier
//     per bundle than mature ones (its control variate's constant has learnt from few steps),
//     which only its own batches show.
//     With one liar among three or more nodes the median is an honest node's value; an honest
//     p is then at most one honest difference from it, whose variance is v (1/m_p + 1/m_q),
//     m_q >= m_min.
//
// The false-alarm rate, derived. Under honesty the deviation over its standard error is a
// Student t whose variance estimate has k - 1 >= 15 degrees of freedom, scaled by at most
// f = 1.13 (batches of the chain's memory length understate v by at most (1.13)^2: for an
// AR(1) chain of lag-one correlation r <= rho_max, a batch of b = ceil(ln 0.01 / ln r) steps
// has Var(b_k) = (v / b) (1 - 2r (1 - r^b) / (b (1 - r) (1 + r))), >= 0.785 v / b for every r). P(|t_15| > kZ / f = 10.6) = 2.3e-8; for the comparison the
// reference variance is the larger of at least two such estimates: 2.9e-12.
// With the thousands of correlated tests a run makes, an honest node is quarantined about
// once in 10^4 runs in the worst case (the furnace without its control variate, where the
// scene's bound is the exact answer), and kFloor keeps the small systematic differences of
// honest nodes (burn-in residue <= 1e-3, float rounding on other devices) out of reach.
//
// What it cannot see: a lie within kZ standard errors (shrinking as 1/sqrt(m)) or below
// kFloor; a lie confined to a few patches of a large chunk; a node that makes up batch noise
// as large as its lie (its own variance widens both of its tests); with two nodes, which of two disagreeing
// nodes lies (only the scene's bound applies); runs whose nodes report no chunks before the
// end (`--exchange-every end`: one state, no batches). PROTOCOL.md section 7 says so.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/mesh.h"

namespace sirad::cluster {

// What the scene allows each chunk: the patches' area weights within their chunk (a_j above),
// and per chunk and channel the bounds of its area-weighted mean radiosity (high: +inf where
// the channel's largest reflectance is 1).
struct ChunkBounds {
  std::vector<double> weight;          // per patch
  std::vector<glm::dvec3> low, high;   // per chunk
};
ChunkBounds chunk_bounds(const PatchMesh& mesh, const std::vector<uint32_t>& starts);

// Bundles after which the chain has forgotten its state: the least g with rho_max^g <= 1e-2
// (at most 1024; 1024 where rho_max >= 1), and at least the 1 / X steps that share one shot
// (shots_per_bundle X < 1): the length of a batch (see above).
uint64_t chain_memory(const PatchMesh& mesh, double shots_per_bundle);

class Plausibility {
 public:
  static constexpr double kZ = 12;             // standard errors
  static constexpr double kFloor = 0.01;       // of the bound, or of the median
  static constexpr uint32_t kMinBatches = 16;  // whole batches before a node's variance is used
  static constexpr uint32_t kSlots = 32;       // batches kept (16 to 32 once they merge)

  // `starts`: chunk_starts of the mesh; `bounds` empty: every patch of a chunk weighs the
  // same and there is no scene bound (test 2 only). `compare`: test 2 (chain rule).
  Plausibility(std::vector<uint32_t> starts, ChunkBounds bounds, uint64_t batch_bundles, bool compare);

  // A node's state of chunk c as the tests see it: per channel sum_j a_j S_j, and m.
  struct Observation {
    glm::dvec3 s{0.0};
    uint64_t count = 0;
  };
  // `sum`: 3 doubles per patch of chunk c (checked by the caller: Aggregate::check).
  Observation observe(uint32_t chunk, const std::vector<double>& sum, uint64_t count) const;

  void add_node();
  // What the tests make of node n's new state `o` of chunk c; changes nothing. `score`: the
  // largest deviation found, over kZ standard errors plus kFloor (above 1 quarantines; 0 when
  // no test applies); `why`: one line saying what is implausible, or "" when nothing is.
  struct Verdict {
    double score = 0;
    std::string why;
  };
  Verdict assess(uint32_t n, uint32_t chunk, const Observation& o) const;
  std::string check(uint32_t n, uint32_t chunk, const Observation& o) const { return assess(n, chunk, o).why; }
  // Takes node n's new state (after check, for every chunk of its message).
  void take(uint32_t n, uint32_t chunk, const Observation& o);
  // Forgets node n's states (quarantined): it is no reference any more.
  void clear(uint32_t n);
  // Node n is a new node (an entry reused: Policy::join): no states, a reference again.
  void forget(uint32_t n);

  // Node n's whole batches of chunk c so far (tests).
  uint32_t batches(uint32_t n, uint32_t chunk) const;

  // A batch: n bundles summing to s; and the jackknife's Var(y) of batches (0 below two).
  struct Batch {
    uint64_t n = 0;
    glm::dvec3 s{0.0};
  };
  static glm::dvec3 jackknife_variance(const std::vector<Batch>& batches);

 private:
  // A node's running state of one chunk: its last observation and its batches.
  struct Stats {
    glm::dvec3 s{0.0};
    uint64_t count = 0;
    uint64_t length = 0;            // bundles a batch needs (doubles when the slots merge)
    uint64_t batched = 0;           // bundles in whole batches
    glm::dvec3 batched_s{0.0};      // and their sum
    std::vector<Batch> batches;
    Stats closed() const;           // the bundles since the last whole batch as one more
  };
  const Stats* stats(uint32_t n, uint32_t chunk) const;
  Stats advanced(const Stats& before, const Observation& o) const;

  std::vector<uint32_t> starts_;
  ChunkBounds bounds_;
  uint64_t batch_bundles_;
  bool compare_;
  std::vector<std::vector<Stats>> stats_;  // [node][chunk], allocated at a node's first state
  std::vector<bool> excluded_;
};

}  // namespace sirad::cluster
