// sirad: a run's own error estimate on one node, by batch means (DESIGN.md section 1, "Error").
// The per-bundle estimates L'(m) of a chain are correlated over a few steps (about 1 / (1 - rho));
// means over batches of many consecutive bundles are nearly independent, so the spread of the
// batch means gives each patch's standard error. The batches double in size as the run grows
// (a fixed number of slots; when all are full, neighbours merge), so every batch is as long as
// possible and the count of full batches stays between K/2 and K.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/mesh.h"

namespace sirad {

// Batch means keep 32 sums per patch (768 bytes each): solvers track them by default only up to
// this many patches (a run that asks for a target error tracks them at any size).
inline constexpr std::size_t kTrackErrorMaxPatches = 100000;

class BatchMeans {
 public:
  // `slots`: K, even, >= 4.
  BatchMeans(std::size_t patches, int slots = 32);

  // Adds the next bundle's estimate (one value per patch).
  void add(std::span<const glm::dvec3> estimate);

  int full_batches() const { return full_; }
  uint64_t batch_size() const { return size_; }

  // The estimated relative RMS error of the mean of everything added, in the measure of
  // relative_rms (solver/metrics.h): sqrt(sum A SE^2 / sum A |mean|^2) over the patches that do not
  // emit (all three channels), SE^2 = var(batch means) / batches. Needs 4 full batches; returns
  // a negative value before that.
  double relative_error(const PatchMesh& mesh) const;

 private:
  std::size_t n_;
  int slots_;
  uint64_t size_ = 1;     // bundles per batch
  int full_ = 0;          // complete batches
  uint64_t filling_ = 0;  // bundles in the batch being filled (index full_)
  std::vector<std::vector<glm::dvec3>> sums_;
};

}  // namespace sirad
