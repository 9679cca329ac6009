// sirad: batch means with doubling batches (see solver/error_estimate.h).
#include "solver/error_estimate.h"

#include <cmath>

#include "util/error.h"

namespace sirad {

BatchMeans::BatchMeans(std::size_t patches, int slots) : n_(patches), slots_(slots) {
  if (slots < 4 || slots % 2 != 0) fail("batch means need an even number of batches >= 4 (got {})", slots);
  sums_.assign(static_cast<std::size_t>(slots), std::vector<glm::dvec3>(patches, glm::dvec3(0.0)));
}

void BatchMeans::add(std::span<const glm::dvec3> estimate) {
  if (estimate.size() != n_) fail("batch means: {} values for {} patches", estimate.size(), n_);
  auto& s = sums_[static_cast<std::size_t>(full_)];
  for (std::size_t j = 0; j < n_; ++j) s[j] += estimate[j];
  if (++filling_ < size_) return;
  filling_ = 0;
  if (++full_ < slots_) return;
  // All slots full: merge neighbours into the first half, batches twice as long.
  for (int g = 0; g < slots_ / 2; ++g) {
    auto& a = sums_[static_cast<std::size_t>(g)];
    const auto& b0 = sums_[static_cast<std::size_t>(2 * g)];
    const auto& b1 = sums_[static_cast<std::size_t>(2 * g + 1)];
    for (std::size_t j = 0; j < n_; ++j) a[j] = b0[j] + b1[j];
  }
  for (int g = slots_ / 2; g < slots_; ++g) std::fill(sums_[static_cast<std::size_t>(g)].begin(), sums_[static_cast<std::size_t>(g)].end(), glm::dvec3(0.0));
  full_ = slots_ / 2;
  size_ *= 2;
}

double BatchMeans::relative_error(const PatchMesh& mesh) const {
  if (full_ < 4) return -1.0;
  if (mesh.size() != n_) fail("batch means: a mesh of {} patches for {}", mesh.size(), n_);
  const double G = full_, b = static_cast<double>(size_);
  double num = 0.0, den = 0.0;
  for (std::size_t j = 0; j < n_; ++j) {
    if (mesh.emits(j)) continue;
    glm::dvec3 mean(0.0), sq(0.0);
    for (int g = 0; g < full_; ++g) {
      glm::dvec3 m = sums_[static_cast<std::size_t>(g)][j] / b;
      mean += m;
      sq += m * m;
    }
    mean /= G;
    glm::dvec3 var = (sq - G * mean * mean) / (G - 1.0);
    double a = mesh.area[j];
    num += a * std::max(0.0, var.x + var.y + var.z) / G;
    den += a * (mean.x * mean.x + mean.y * mean.y + mean.z * mean.z);
  }
  return den > 0.0 ? std::sqrt(num / den) : -1.0;
}

}  // namespace sirad
