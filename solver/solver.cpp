// sirad: the single-node stochastic iteration: update rules, burn-in, double accumulation.
#include "solver/solver.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/error.h"

namespace sirad {

UpdateRule parse_update_rule(const std::string& name) {
  if (name == "chain") return UpdateRule::chain;
  if (name == "average") return UpdateRule::average;
  fail("unknown update rule '{}' (expected chain or average)", name);
}

const char* to_string(UpdateRule rule) { return rule == UpdateRule::chain ? "chain" : "average"; }

int auto_burn_in(const PatchMesh& mesh) {
  float rho_max = 0.0f;
  for (const auto& m : mesh.materials) rho_max = std::max({rho_max, m.reflectance.x, m.reflectance.y, m.reflectance.z});
  if (rho_max <= 0.0f) return 0;
  if (rho_max >= 1.0f) return 64;
  double k = std::ceil(std::log(1e-3) / std::log(static_cast<double>(rho_max)));
  return static_cast<int>(std::min(k, 64.0));
}

ShotRange shots_of_step(double x, uint64_t index) {
  if (!(x > 0.0)) return {};
  auto at = [x](uint64_t k) { return static_cast<uint64_t>(std::floor(static_cast<double>(k) * x)); };
  uint64_t a = at(index), b = at(index + 1);
  return {a, std::max<uint64_t>(b - a, 1)};
}

void check_first_shot(double x, int resolution) {
  if (!(x >= 0.0) || x > 1024.0) fail("shots per bundle must be in [0, 1024] (got {})", x);
  if (resolution != 0 && (resolution < 4 || resolution % 2 != 0 || resolution > 2048))
    fail("shot resolution must be 0 (auto) or even in [4, 2048] (got {})", resolution);
}

Solver::Solver(const PatchMesh& mesh, BundleEngine& engine, const SolverOptions& options, ShotEngine* shots)
    : mesh_(mesh), engine_(engine), options_(options) {
  check_first_shot(options.shots_per_bundle, options.shot_resolution);
  if (options.shots_per_bundle > 0.0) {
    if (shots == nullptr) fail("first shot: no shot engine given");
    // A scene that emits nothing has no direct light to shoot: D = 0 and the plain iteration.
    // Only the emitters whose light the shot estimates well (shot_emitter_table); the others'
    // emission stays in what the bundles carry.
    emitters_ = shot_emitter_table(mesh);
    if (!emitters_.empty()) shots_ = shots;
    shot_emission_.assign(mesh.size(), glm::dvec3(0.0));
    for (uint32_t j : emitters_.patch) shot_emission_[j] = glm::dvec3(mesh.emission(j));
    shot_resolution_ = options.shot_resolution ? options.shot_resolution : auto_shot_resolution(mesh);
  }
  if (options.grid < 0 || options.grid == 1) fail("grid must be at least 2 (got {})", options.grid);
  grid_ = options.grid == 0 ? auto_grid(mesh) : options.grid;
  burn_in_ = options.rule == UpdateRule::average ? 0 : (options.burn_in < 0 ? auto_burn_in(mesh) : options.burn_in);
  batch_ = options.warm ? 1 : options.batch > 0 ? options.batch : std::max<uint32_t>(1, engine.preferred_batch());
  if (options.directions == Directions::stratified && options.rule != UpdateRule::chain)
    fail("stratified directions need the chain rule (under average they bias the estimate: engine/bundle.cpp)");
  sampling_ = sampling_plan(mesh, options.directions);
  if (options.interleave) sampling_.interleave = options.interleave;
  if (options.strata_side) sampling_.side = options.strata_side;
  two_delta_ = 2.0 * cell_area(mesh, grid_);
  const std::size_t n = mesh.size();
  sum_.assign(n, glm::dvec3(0.0));
  // Batch means assume the chain's estimates; under the average rule each one depends on the
  // running mean of all before it and batch means would understate the error: not tracked.
  if (options.track_error && options.rule == UpdateRule::chain) batches_ = std::make_unique<BatchMeans>(n);
  source_.resize(n);
  for (std::size_t j = 0; j < n; ++j) source_[j] = glm::dvec3(mesh.emission(j));
  state_ = source_;
  if (const WarmStart* w = options.warm) {
    if (options.rule != UpdateRule::chain || shots_) fail("a warm start needs the chain rule and no first shot");
    if (!w->before || !w->engine || w->match.size() != n || w->radiosity.size() != w->before->size())
      fail("warm start: {} matches for {} patches, {} values for the previous run's patches", w->match.size(), n,
           w->radiosity.size());
    if (w->before->bound_radius != mesh.bound_radius || w->before->bound_center != mesh.bound_center)
      fail("warm start: the previous run's patches and these do not share one bounding sphere (share_bound)");
    warm_input_.resize(w->before->size());
    for (std::size_t i = 0; i < warm_input_.size(); ++i) warm_input_[i] = glm::vec4(w->radiosity[i], 0.0f);
    warm_offset_.assign(n, glm::dvec3(0.0));
    for (std::size_t j = 0; j < n; ++j)
      if (const int64_t i = w->match[j]; i >= 0) {
        if (static_cast<std::size_t>(i) >= w->before->size()) fail("warm start: patch {} matched to {} of {}", j, i, w->before->size());
        const auto k = static_cast<uint32_t>(i);
        state_[j] = glm::dvec3(w->radiosity[k]);
        warm_offset_[j] = glm::dvec3(w->radiosity[k]) - glm::dvec3(w->before->emission(k));
      }
  }
  input_.resize(n);
  incoming_sum_.assign(n, glm::dvec3(0.0));
  direct_sum_.assign(n, glm::dvec3(0.0));
  // Burn-in: advance the chain from E without counting, on its own stream of bundles.
  for (int k = 0; k < burn_in_; ++k) {
    if (options.cancelled && options.cancelled()) fail("set-up interrupted after {} of {} burn-in bundles", k, burn_in_);
    uint64_t index = (options.chain_id << 32) | static_cast<uint64_t>(k);
    update_source(index, Stream::burn_in_shots);
    run_bundle(index, Stream::burn_in);
    transport(result_);
    state_.swap(next_state_);
  }
}

double Solver::error_estimate() const {
  if (!batches_) return -1.0;
  const double own = batches_->relative_error(mesh_);
  if (own < 0.0 || !options_.warm) return own;
  return std::sqrt(own * own + options_.warm->error * options_.warm->error);
}

bool Solver::error_estimate_ready() const {
  if (!batches_ || batches_->full_batches() < 8) return false;
  double x = shots_ ? options_.shots_per_bundle : 0.0;
  double shared = x > 0.0 && x < 1.0 ? std::ceil(4.0 / x) : 4.0;
  // The estimates of one batch share their state: a batch of means spans at least four of them.
  shared = std::max(shared, 4.0 * static_cast<double>(batch_));
  return static_cast<double>(batches_->batch_size()) >= std::max(4.0, shared);
}

void Solver::update_source(uint64_t index, Stream stream) {
  if (shots_ == nullptr) return;
  ShotRange range = shots_of_step(options_.shots_per_bundle, index);
  if (stream == cached_stream_ && range.first == cached_.first && range.count == cached_.count) return;
  // Stratified directions stratify the counted shots' points on the emitters too (engine/shot.h).
  const bool stratified = sampling_.directions == Directions::stratified && stream == Stream::shots;
  run_shots(mesh_, emitters_, *shots_, shot_resolution_, options_.seed, range.first, range.count, stream, stratified,
            shot_sums_, shot_scratch_);
  const ShotSums& sums = shot_sums_;
  shots_rendered_ += sums.shots;
  direct_shots_ += sums.shots;
  for (std::size_t j = 0; j < source_.size(); ++j) {
    source_[j] = glm::dvec3(mesh_.emission(j)) + sums.direct[j] / static_cast<double>(sums.shots);
    direct_sum_[j] += sums.direct[j];
  }
  cached_stream_ = stream;
  cached_ = range;
}

void Solver::set_input() {
  // With a first shot the bundles transport Y = B - E_s, E_s the emission of the emitters shot
  // from (their light is already in D); the other emitters' emission E_l stays in Y:
  // Y = E_l + D + rho F Y, and the estimate E + D_m + rho T(Y) has mean E_s + Y = B.
  for (std::size_t j = 0; j < state_.size(); ++j)
    input_[j] = glm::vec4(glm::vec3(shots_ ? state_[j] - shot_emission_[j] : state_[j]), 0.0f);
}

void Solver::add_estimate(const std::vector<glm::dvec3>& estimate) {
  ++count_;
  for (std::size_t j = 0; j < estimate.size(); ++j) sum_[j] += estimate[j];
  if (batches_) batches_->add(estimate);
}

void Solver::run_bundle(uint64_t index, Stream stream) {
  set_input();
  SiradBundle b = make_bundle(mesh_, grid_, options_.seed, index, stream, sampling_);
  engine_.run(b, input_, result_);
  crossings_ += result_.crossings;
  if (const WarmStart* w = options_.warm) {  // the same lines through the old scene, carrying P
    w->engine->run(make_bundle(*w->before, grid_, options_.seed, index, stream, sampling_), warm_input_, warm_result_);
    crossings_ += warm_result_.crossings;
  }
}

const std::vector<glm::dvec3>& Solver::transport(const BundleResult& r) {
  // The incoming radiance of patch j, I_j = sum_i F_ji X_i, estimated by one bundle:
  //     I*_j = (2 delta / A_j) g_j                       (g_j: the front neighbours' X summed over
  //                                                       the h_j lines crossing j; DESIGN.md)
  // E[h_j 2 delta / A_j] = 1 (the same fact that makes I* unbiased for X = 1), so for any
  // constant c_j fixed before the bundle is drawn
  //     I*_j + c_j (1 - (2 delta / A_j) h_j)  =  c_j + (2 delta / A_j) sum over lines (X_seen - c_j)
  // is unbiased too: the constant control variate of stochastic radiosity (Bekaert), whose
  // hemisphere integral is exactly c_j. Its variance is that of the deviations X_seen - c_j:
  // the noise of a constant's transport (h_j is a lattice count, and one direction weighs the
  // hemisphere with 2 |cos|: relative variance 1/3 even for uniform light) is gone. c_j is the
  // mean of patch j's earlier incoming estimates (0 before the first): fixed given the past,
  // so each step stays conditionally unbiased and so does the average of the chain's steps.
  // The chain's next input (next_state_) gets the same transport, but the direct light in it
  // is the mean of every shot so far, D-bar, not this step's D_m: E[D-bar] = D as well, so
  // E[next] = E + D + T E[state] still has B as its fixed point (each transport is linear and
  // independent of its input), while the transported input is far less noisy (one shot leaves
  // most patches with a few samples or none). The estimate keeps D_m, so the run's average
  // weighs every shot equally.
  const bool cv = options_.control_variate && incoming_count_ > 0;
  const double shots = direct_shots_ > 0 ? 1.0 / static_cast<double>(direct_shots_) : 0.0;
  next_state_.resize(mesh_.size());
  const double past = incoming_count_ > 0 ? 1.0 / static_cast<double>(incoming_count_) : 0.0;
  std::vector<glm::dvec3>& out = estimate_;
  out.resize(mesh_.size());
  const WarmStart* warm = options_.warm;
  for (std::size_t j = 0; j < out.size(); ++j) {
    double w = two_delta_ / mesh_.area[j];
    glm::dvec3 in = w * glm::dvec3(r.gathered[j]);
    const int64_t old = warm ? warm->match[j] : -1;
    // P's control variate (warm_start.h) where the patch was one of the last run's; it takes the
    // place of the constant one, whose lattice noise the same lines' old estimate cancels.
    if (cv && old < 0) in += incoming_sum_[j] * past * (1.0 - w * static_cast<double>(r.hits[j]));
    incoming_sum_[j] += in;
    glm::dvec3 reflected = glm::dvec3(mesh_.reflectance(j)) * in;
    if (old >= 0) {
      const auto i = static_cast<uint32_t>(old);
      const glm::dvec3 in_old = (two_delta_ / warm->before->area[i]) * glm::dvec3(warm_result_.gathered[i]);
      reflected += warm_offset_[j] - glm::dvec3(warm->before->reflectance(i)) * in_old;
    }
    out[j] = source_[j] + reflected;
    next_state_[j] = shots_ ? glm::dvec3(mesh_.emission(j)) + direct_sum_[j] * shots + reflected : out[j];
  }
  ++incoming_count_;
  return out;
}

void Solver::step(uint64_t index) {
  update_source(index, Stream::shots);
  run_bundle(index, Stream::bundles);
  add_estimate(transport(result_));
  if (options_.rule == UpdateRule::chain) {
    state_.swap(next_state_);
  } else {
    update_average_state();
  }
}

void Solver::step_batch(uint64_t first, uint32_t count) {
  if (count <= 1 || options_.warm) {
    for (uint32_t i = 0; i < count; ++i) step(first + i);
    return;
  }
  set_input();  // every bundle of the batch transports it
  batch_bundles_.resize(count);
  batch_results_.resize(count);
  for (uint32_t i = 0; i < count; ++i)
    batch_bundles_[i] = make_bundle(mesh_, grid_, options_.seed, first + i, Stream::bundles, sampling_);
  engine_.run_batch(batch_bundles_, input_, batch_results_);
  batch_next_.assign(state_.size(), glm::dvec3(0.0));
  for (uint32_t i = 0; i < count; ++i) {
    // Each estimate as step() makes it: its own shots, the control variate's constant from the
    // incoming estimates before it (fixed given the bundles before: this one's directions are
    // independent of theirs), so each is unbiased for E + T (state) on its own.
    update_source(first + i, Stream::shots);
    crossings_ += batch_results_[i].crossings;
    add_estimate(transport(batch_results_[i]));
    for (std::size_t j = 0; j < batch_next_.size(); ++j) batch_next_[j] += next_state_[j];
  }
  std::swap(result_, batch_results_.back());  // last(): the batch's last bundle (no copy)
  if (options_.rule == UpdateRule::chain) {
    const double inv = 1.0 / static_cast<double>(count);
    for (std::size_t j = 0; j < state_.size(); ++j) state_[j] = batch_next_[j] * inv;
  } else {
    update_average_state();
  }
}

void Solver::update_average_state() {
  // L_p = (S_p + O_p) / (m_p + M_p): the average over every sample this node has seen.
  const bool others = !others_count_.empty();
  for (std::size_t j = 0; j < state_.size(); ++j) {
    uint64_t m = count_ + (others ? others_count_[j] : 0);
    if (m > 0) state_[j] = (others ? sum_[j] + others_sum_[j] : sum_[j]) / static_cast<double>(m);
  }
}

void Solver::absorb(std::size_t first, std::span<const glm::dvec3> others, uint64_t others_count) {
  if (first > mesh_.size() || others.size() > mesh_.size() - first)
    fail("absorb: patches [{}, {}) outside the mesh's {}", first, first + others.size(), mesh_.size());
  // The others' sums as the coordinator checks every node's (cluster::Aggregate::check): finite
  // and within count x FLT_MAX; checked before any is taken.
  const double limit = static_cast<double>(others_count) * static_cast<double>(std::numeric_limits<float>::max());
  for (std::size_t i = 0; i < others.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(others[i][k]) || std::fabs(others[i][k]) > limit)
        fail("absorb: patch {} value {} for {} bundles", first + i, others[i][k], others_count);
  // Only the average rule's input uses them (allocated at the first exchange: 32 B per patch).
  if (options_.rule != UpdateRule::average) return;
  if (others_count_.empty()) {
    others_sum_.assign(mesh_.size(), glm::dvec3(0.0));
    others_count_.assign(mesh_.size(), 0);
  }
  for (std::size_t i = 0; i < others.size(); ++i) {
    others_sum_[first + i] = others[i];
    others_count_[first + i] = others_count;
  }
  update_average_state();
}

std::vector<glm::vec3> Solver::estimate() const {
  std::vector<glm::vec3> out(mesh_.size());
  for (std::size_t j = 0; j < out.size(); ++j)
    out[j] = count_ == 0 ? mesh_.emission(j) : glm::vec3(sum_[j] / static_cast<double>(count_));
  return out;
}

}  // namespace sirad
