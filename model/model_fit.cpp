// sirad: the model's scene parameters from real bundles (see model/model_fit.h).
#include "model/model_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "util/error.h"

namespace sirad::model {

namespace {

// One transport of `x` by a fresh bundle, reflected: rho T* x (no emission added), with the
// constant control variate c = the area-weighted mean of x (fixed before the bundle, so still
// unbiased: c (1 - 2 delta n_j / A_j) has mean 0): in a room of even light it cancels the
// noise of how many lines cross each patch, which would otherwise dominate a bounce's energy.
// `plain` leaves it out (the first bounce's sigma_1 is the plain estimator's, the paper's).
// Keeps each bundle's time and counts the bundles.
class Bouncer {
 public:
  Bouncer(const PatchMesh& mesh, BundleEngine& engine, int grid, uint64_t seed)
      : mesh_(mesh), engine_(engine), grid_(grid), seed_(seed), two_delta_(2.0 * cell_area(mesh, grid)) {
    for (std::size_t j = 0; j < mesh.size(); ++j) total_area_ += mesh.area[j];
  }

  void bounce(const std::vector<glm::vec4>& x, std::vector<glm::vec4>& out, bool plain) {
    const std::size_t n = mesh_.size();
    SiradBundle b = make_bundle(mesh_, grid_, seed_, index_++, Stream::fit);
    auto t0 = std::chrono::steady_clock::now();
    engine_.run(b, x, result_);
    times_.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    glm::dvec3 c(0.0);
    if (!plain)
      for (std::size_t j = 0; j < n; ++j) c += static_cast<double>(mesh_.area[j]) * glm::dvec3(x[j]) / total_area_;
    out.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      double w = two_delta_ / mesh_.area[j];
      glm::dvec3 in = w * glm::dvec3(result_.gathered[j]) + c * (1.0 - w * static_cast<double>(result_.hits[j]));
      out[j] = glm::vec4(glm::vec3(glm::dvec3(mesh_.reflectance(j)) * in), 0.0f);
    }
  }

  double energy(const std::vector<glm::vec4>& x) const {
    double e = 0.0;
    for (std::size_t j = 0; j < mesh_.size(); ++j) e += mesh_.area[j] * (static_cast<double>(x[j].x) + x[j].y + x[j].z);
    return e;
  }

  uint64_t bundles() const { return index_; }
  // The median time of a bundle so far.
  double median_time() {
    std::nth_element(times_.begin(), times_.begin() + static_cast<long>(times_.size() / 2), times_.end());
    return times_[times_.size() / 2];
  }

 private:
  const PatchMesh& mesh_;
  BundleEngine& engine_;
  const int grid_;
  const uint64_t seed_;
  const double two_delta_;
  double total_area_ = 0.0;
  uint64_t index_ = 0;
  std::vector<double> times_;
  BundleResult result_;
};

// The contraction a, from o.chains chains of o.bounces bounces from E, with its standard error.
void fit_contraction(Bouncer& t, const std::vector<glm::vec4>& emission, const FitOptions& o, SceneFit& fit) {
  std::vector<double> num(o.chains, 0.0), den(o.chains, 0.0);
  for (int c = 0; c < o.chains; ++c) {
    std::vector<glm::vec4> x = emission, next;
    std::vector<double> e;
    for (int k = 0; k < o.bounces; ++k) {
      t.bounce(x, next, false);
      x.swap(next);
      e.push_back(t.energy(x));  // e[k]: bounce k + 1
    }
    for (int k = 0; k + 1 < o.bounces; ++k) {  // bounce k + 2 over bounce k + 1
      den[c] += e[k];
      num[c] += e[k + 1];
    }
  }
  double sn = 0.0, sd = 0.0;
  for (int c = 0; c < o.chains; ++c) {
    sn += num[c];
    sd += den[c];
  }
  if (!(sd > 0.0)) fail("model fit: no light reached a second bounce (a = 0?)");
  fit.contraction = sn / sd;
  // Its SE by the delta method over the chains (ratio of means of independent pairs).
  double var = 0.0;
  for (int c = 0; c < o.chains; ++c) {
    double r = num[c] - fit.contraction * den[c];
    var += r * r;
  }
  var /= static_cast<double>(o.chains - 1);
  fit.contraction_se = std::sqrt(var / o.chains) / (sd / o.chains);
}

// sigma_1 / C: the spread of o.first_bounce one-bundle first bounces rho T* E over their level.
double fit_sigma_ratio(Bouncer& t, const PatchMesh& mesh, const std::vector<glm::vec4>& emission, const FitOptions& o) {
  const std::size_t n = mesh.size();
  std::vector<double> mean(n, 0.0), m2(n, 0.0);
  std::vector<glm::vec4> first;
  for (int b = 0; b < o.first_bounce; ++b) {
    t.bounce(emission, first, true);
    for (std::size_t j = 0; j < n; ++j) {
      double v = static_cast<double>(first[j].x) + first[j].y + first[j].z;
      double d = v - mean[j];
      mean[j] += d / (b + 1);
      m2[j] += d * (v - mean[j]);
    }
  }
  double area = 0.0, level = 0.0, spread = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    glm::vec3 r = mesh.reflectance(j);
    if (!(r.x + r.y + r.z > 0.0f)) continue;
    area += mesh.area[j];
    level += mesh.area[j] * mean[j];
    spread += mesh.area[j] * m2[j] / (o.first_bounce - 1);
  }
  if (!(level > 0.0)) fail("model fit: the first bounce reached no reflecting patch");
  return std::sqrt(spread / area) / (level / area);
}

}  // namespace

SceneFit fit_scene(const PatchMesh& mesh, BundleEngine& engine, const FitOptions& o) {
  const std::size_t n = mesh.size();
  if (n == 0) fail("model fit: the mesh has no patches");
  if (o.chains < 2 || o.bounces < 3 || o.first_bounce < 2)
    fail("model fit: needs at least 2 chains of 3 bounces and 2 first-bounce bundles");
  bool emits = false, reflects = false;
  for (std::size_t j = 0; j < n; ++j) {
    emits = emits || mesh.emits(j);
    glm::vec3 r = mesh.reflectance(j);
    reflects = reflects || r.x + r.y + r.z > 0.0f;
  }
  if (!emits || !reflects) fail("model fit: the scene must emit and reflect light");
  Bouncer t(mesh, engine, o.grid ? o.grid : auto_grid(mesh), o.seed);
  std::vector<glm::vec4> emission(n);
  for (std::size_t j = 0; j < n; ++j) emission[j] = glm::vec4(mesh.emission(j), 0.0f);
  SceneFit fit;
  fit_contraction(t, emission, o, fit);
  fit.sigma_ratio = fit_sigma_ratio(t, mesh, emission, o);
  fit.t_iteration = t.median_time();
  fit.bundles = t.bundles();
  return fit;
}

}  // namespace sirad::model
