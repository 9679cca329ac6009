// sirad: a node's part of one run (see worker.h).
#include "cluster/worker.h"

#include <algorithm>

#include "util/error.h"

namespace sirad::cluster {

std::vector<double> flatten(std::span<const glm::dvec3> values) {
  std::vector<double> flat;
  flat.reserve(3 * values.size());
  for (const glm::dvec3& v : values) {
    flat.push_back(v.x);
    flat.push_back(v.y);
    flat.push_back(v.z);
  }
  return flat;
}

std::vector<glm::dvec3> unflatten(std::span<const double> flat) {
  std::vector<glm::dvec3> values(flat.size() / 3);
  for (std::size_t j = 0; j < values.size(); ++j) values[j] = glm::dvec3(flat[3 * j], flat[3 * j + 1], flat[3 * j + 2]);
  return values;
}

Worker::Worker(const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots, const RunSettings& settings, uint32_t index,
               std::span<const uint32_t> starts, std::function<bool()> cancelled) {
  if (starts.empty() || starts.front() != 0) fail("the run's chunks do not start at patch 0");
  for (std::size_t c = 1; c < starts.size(); ++c)
    if (starts[c] <= starts[c - 1] || starts[c] >= mesh.size()) fail("the run's chunk {} starts out of order or beyond the mesh", c);
  starts_.assign(starts.begin(), starts.end());
  starts_.push_back(static_cast<uint32_t>(mesh.size()));
  SolverOptions options = solver_options(settings, mesh, index);
  options.cancelled = std::move(cancelled);
  solver_ = std::make_unique<Solver>(mesh, engine, options, shots);
}

bool Worker::run(std::span<const Range> ranges, const std::function<bool()>& between) {
  // The solver's batches (one launch of several bundles on a GPU) within each range.
  for (const Range& r : ranges)
    for (uint64_t k = r.first; k < r.last;) {
      const auto count = static_cast<uint32_t>(std::min<uint64_t>(solver_->batch(), r.last - k));
      solver_->step_batch(k, count);
      k += count;
      if (between && !between()) return false;
    }
  return true;
}

std::vector<ChunkState> Worker::states(std::span<const uint32_t> chunks) const {
  std::vector<ChunkState> out;
  const std::span<const glm::dvec3> sum = solver_->sum();
  for (uint32_t c : chunks) {
    if (c >= this->chunks()) fail("chunk {} of a run of {} chunks", c, this->chunks());
    out.push_back({c, flatten(sum.subspan(starts_[c], starts_[c + 1] - starts_[c])), solver_->bundles()});
  }
  return out;
}

std::vector<ChunkState> Worker::all_states() const {
  std::vector<uint32_t> all(chunks());
  for (uint32_t c = 0; c < all.size(); ++c) all[c] = c;
  return states(all);
}

void Worker::absorb(uint32_t chunk, std::span<const double> sum, uint64_t count) {
  if (chunk >= chunks()) fail("chunk {} of a run of {} chunks", chunk, chunks());
  const std::size_t patches = starts_[chunk + 1] - starts_[chunk];
  if (sum.size() != 3 * patches) fail("chunk {}: {} values for {} patches", chunk, sum.size(), patches);
  solver_->absorb(starts_[chunk], unflatten(sum), count);
}

double Worker::reported_error() const { return solver_->error_estimate_ready() ? solver_->error_estimate() : 0.0; }

}  // namespace sirad::cluster
