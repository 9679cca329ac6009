// sirad: stochastic iteration on one node (DESIGN.md section 1). Each step runs one bundle —
// one random transport T* — on a BundleEngine and folds it into the running average
//     L(m) = L(m-1) + (L'(m) - L(m-1)) / m        (kept as a double-precision sum)
// with one of the two update rules for the transport's input:
//     chain   (default)  L'(m) = E + T*_m L'(m-1)
//     average (paper)    L'(m) = E + T*_m L(m-1)
// The solver knows nothing of devices or networks: engines run bundles, drivers choose indices.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <functional>

#include <glm/vec3.hpp>

#include <memory>

#include "engine/bundle.h"
#include "engine/shot.h"
#include "scene/mesh.h"
#include "solver/error_estimate.h"
#include "solver/warm_start.h"

namespace sirad {

enum class UpdateRule { chain, average };

UpdateRule parse_update_rule(const std::string& name);  // "chain" | "average"
const char* to_string(UpdateRule rule);

struct SolverOptions {
  uint64_t seed = 1;
  int grid = 0;            // lines per side; 0: auto_grid(mesh)
  UpdateRule rule = UpdateRule::chain;
  int burn_in = -1;        // chain only: bundles run before counting; -1: auto
  uint64_t chain_id = 0;   // keeps the burn-in bundles of different chains apart
  Directions directions = Directions::random;  // stratified: chain rule only (engine/bundle.h)
  uint32_t interleave = 0, strata_side = 0;      // stratified G and n; 0: sampling_plan's
  // First shot (engine/shot.h): shots per bundle (0: off). Step k uses the shots
  // [floor(k X), floor((k + 1) X)) of the run, or shot floor(k X) when that range is empty.
  double shots_per_bundle = 0.0;
  int shot_resolution = 0;  // hemicube side H; 0: auto_shot_resolution(mesh)
  bool track_error = false; // keep batch means of the estimates (error_estimate()); chain rule only
  // The transport's constant control variate (Solver::transport): unbiased either way; on,
  // it removes the noise of how many lines happen to cross a patch and of their cosine.
  bool control_variate = true;
  // A start from the last run (solver/warm_start.h): chain rule, no first shot. Its patches'
  // state starts at P (elsewhere at E), and each step's estimate there takes P's control variate.
  const WarmStart* warm = nullptr;
  // Bundles per step of the chain (step_batch; DESIGN.md "Batches"): B bundles from one state,
  // the next state their mean. 0: the engine's preference (BundleEngine::preferred_batch: 1 but
  // on the wide path). A warm start runs single bundles.
  uint32_t batch = 0;
  // Asked between burn-in bundles (a burn-in may run up to 2^20 of them); true: the solver's
  // construction stops with sirad::Error "set-up interrupted" (a node told to stop).
  std::function<bool()> cancelled;
};

// The shots step `index` of `stream` uses under `shots_per_bundle` X: [first, first + count).
struct ShotRange {
  uint64_t first = 0, count = 0;
};
ShotRange shots_of_step(double shots_per_bundle, uint64_t index);
// Throws sirad::Error for shots per bundle outside [0, 1024] or a resolution
// that is neither 0 (auto) nor even in [4, 8192].
void check_first_shot(double shots_per_bundle, int shot_resolution);

// Burn-in that brings the chain's start-up bias below 1e-3 of its initial value:
// the smallest k with rho_max^k < 1e-3, capped at 64 (0 for a scene that reflects nothing).
int auto_burn_in(const PatchMesh& mesh);

class Solver {
 public:
  // With options.shots_per_bundle > 0 every step also renders its first-shot samples on
  // `shots` and becomes  L'(m) = E + D_m + T*_m (S(m-1) - E):  the bundles carry only the
  // indirect part Y = B - E, and D_m, an unbiased estimate of the direct light D = rho F E
  // independent of the transport, replaces its noisy part. Under the chain rule the input
  // S(m) = E + D-bar_m + T*_m (S(m-1) - E) differs from L'(m) only in its direct light: the
  // mean of all shots so far (see transport()). Everything the solver reports (estimate, sum,
  // state) stays in units of B.
  Solver(const PatchMesh& mesh, BundleEngine& engine, const SolverOptions& options,
         ShotEngine* shots = nullptr);

  // Runs counted bundle `index` of the run and adds its estimate to the average.
  void step(uint64_t index);
  // Runs counted bundles first .. first + count - 1 as one step of the chain: every one of
  // them from the same state (one launch where the engine batches), each estimate added to the
  // average as step() adds it, and the next state the mean of their next states (chain rule;
  // the average rule's input is the running average, as after step()). count 1 is step(first).
  void step_batch(uint64_t first, uint32_t count);
  // The bundles step_batch takes at a time: options.batch, else the engine's preference.
  uint32_t batch() const { return batch_; }

  uint64_t bundles() const { return count_; }
  bool first_shot() const { return shots_ != nullptr; }
  int shot_resolution() const { return shot_resolution_; }
  uint64_t shots_rendered() const { return shots_rendered_; }
  // With options.track_error: the estimated relative RMS error of estimate() per non-emitting
  // patch (solver/error_estimate.h), or a negative value while there are too few bundles.
  // With a warm start, P's own error is in it too (the run's answer carries it: warm_start.h).
  double error_estimate() const;
  int batch_count() const { return batches_ ? batches_->full_batches() : 0; }
  // Whether error_estimate() can be trusted for stopping: at least 8 full batches, each long
  // against the correlations between consecutive estimates: the chain's (a few steps) and, with
  // fewer than one shot per bundle, the 1 / X steps that share a shot: size >= max(4, 4 / X).
  bool error_estimate_ready() const;
  uint64_t crossings() const { return crossings_; }
  int grid() const { return grid_; }
  int burn_in() const { return burn_in_; }
  const Sampling& sampling() const { return sampling_; }
  const SolverOptions& options() const { return options_; }

  // The average of the per-bundle estimates, L(m) (the emission before any bundle).
  std::vector<glm::vec3> estimate() const;
  // Sum of the per-bundle estimates L'(1..m), double precision.
  const std::vector<glm::dvec3>& sum() const { return sum_; }
  // The input of the next transport: L'(m) under chain (S(m) with a first shot), L(m) under average.
  const std::vector<glm::dvec3>& state() const { return state_; }
  // The last bundle's raw result (gathered sums and hits), for tests and diagnostics.
  const BundleResult& last() const { return result_; }

  // The other nodes' aggregate for patches [first, first + others.size()) (DESIGN.md "Many
  // nodes"): their summed estimates and their count, as the last exchange gave them. Under the
  // average rule the next transport's input becomes (S_p + O_p) / (m_p + M_p) there; under
  // chain the values are checked and the chain is untouched (its estimate is the node's own).
  void absorb(std::size_t first, std::span<const glm::dvec3> others, uint64_t others_count);

  // E (+ D) + rho * (the incoming radiance estimated from `gathered`): one transport of the
  // radiance that produced it. Records the incoming estimate for the next control variate.
  // The result lives in the solver until the next transport (no allocation per step).
  const std::vector<glm::dvec3>& transport(const BundleResult& gathered);

 private:
  // input_ from the state: what the next bundle (or batch) transports.
  void set_input();
  // Adds one step's estimate to the average and the error's batch means.
  void add_estimate(const std::vector<glm::dvec3>& estimate);
  void run_bundle(uint64_t index, Stream stream);

  const PatchMesh& mesh_;
  BundleEngine& engine_;
  SolverOptions options_;
  int grid_;
  int burn_in_;
  uint32_t batch_ = 1;
  std::vector<SiradBundle> batch_bundles_;      // step_batch's scratch
  std::vector<BundleResult> batch_results_;
  std::vector<glm::dvec3> batch_next_;
  Sampling sampling_;
  double two_delta_;
  void update_average_state();

  void update_source(uint64_t index, Stream stream);
  ShotEngine* shots_ = nullptr;
  EmitterTable emitters_;                  // built once: every step's shots draw from it
  std::vector<glm::dvec3> shot_emission_;  // E_s: the emission of the patches in emitters_
  ShotSums shot_sums_;                     // the last update_source's shots
  ShotScratch shot_scratch_;               // reused by every shot
  std::unique_ptr<BatchMeans> batches_;
  int shot_resolution_ = 0;
  uint64_t shots_rendered_ = 0;
  Stream cached_stream_ = Stream::shots;
  ShotRange cached_{0, 0};
  std::vector<glm::dvec3> source_;         // E, or E + D_m of the step with a first shot
  std::vector<glm::dvec3> sum_, state_;
  std::vector<glm::dvec3> others_sum_;     // O_p per patch (average rule, after an exchange)
  std::vector<uint64_t> others_count_;     // M_p per patch (empty until then)
  std::vector<glm::vec4> input_;
  std::vector<glm::dvec3> incoming_sum_;   // per patch: sum of the incoming estimates so far
  uint64_t incoming_count_ = 0;            // transports summed there (burn-in included)
  std::vector<glm::dvec3> direct_sum_;     // sum of every shot's direct light so far (D-bar * shots)
  uint64_t direct_shots_ = 0;
  std::vector<glm::dvec3> next_state_;     // the chain's next input, made by transport()
  std::vector<glm::dvec3> estimate_;       // the last transport's estimate L'(m)
  // Warm start: P as the old engine's input, the same bundle's result on the old patches, and
  // per new patch P_i - E_i (i its old patch; 0 where none).
  std::vector<glm::vec4> warm_input_;
  BundleResult warm_result_;
  std::vector<glm::dvec3> warm_offset_;
  BundleResult result_;
  uint64_t count_ = 0, crossings_ = 0;
};

}  // namespace sirad
