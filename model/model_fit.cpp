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
  const int grid = o.grid ? o.grid : auto_grid(mesh);
  const double two_delta = 2.0 * cell_area(mesh, grid);
  uint64_t index = 0;
  SceneFit fit;
  std::vector<double> times;
  BundleResult result;
  std::vector<glm::vec4> input(n);
  double total_area = 0.0;
  for (std::size_t j = 0; j < n; ++j) total_area += mesh.area[j];
  // One transport of `x` by a fresh bundle, reflected: rho T* x (no emission added), with the
  // constant control variate c = the area-weighted mean of x (fixed before the bundle, so still
  // unbiased: c (1 - 2 delta n_j / A_j) has mean 0): in a room of even light it cancels the
  // noise of how many lines cross each patch, which would otherwise dominate a bounce's energy.
  // `plain` leaves it out (the first bounce's sigma_1 is the plain estimator's, the paper's).
  auto bounce = [&](const std::vector<glm::vec4>& x, std::vector<glm::vec4>& out, bool plain) {
    SiradBundle b = make_bundle(mesh, grid, o.seed, index++, Stream::fit);
    auto t0 = std::chrono::steady_clock::now();
    engine.run(b, x, result);
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    glm::dvec3 c(0.0);
    if (!plain)
      for (std::size_t j = 0; j < n; ++j) c += static_cast<double>(mesh.area[j]) * glm::dvec3(x[j]) / total_area;
    out.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      double w = two_delta / mesh.area[j];
      glm::dvec3 in = w * glm::dvec3(result.gathered[j]) + c * (1.0 - w * static_cast<double>(result.hits[j]));
      out[j] = glm::vec4(glm::vec3(glm::dvec3(mesh.reflectance(j)) * in), 0.0f);
    }
  };
  auto energy = [&](const std::vector<glm::vec4>& x) {
    double e = 0.0;
    for (std::size_t j = 0; j < n; ++j) e += mesh.area[j] * (static_cast<double>(x[j].x) + x[j].y + x[j].z);
    return e;
  };
  std::vector<glm::vec4> emission(n);
  for (std::size_t j = 0; j < n; ++j) emission[j] = glm::vec4(mesh.emission(j), 0.0f);

  // The contraction: chains of bounces from E.
  std::vector<double> num(o.chains, 0.0), den(o.chains, 0.0);
  for (int c = 0; c < o.chains; ++c) {
    std::vector<glm::vec4> x = emission, next;
    std::vector<double> e;
    for (int k = 0; k < o.bounces; ++k) {
      bounce(x, next, false);
      x.swap(next);
      e.push_back(energy(x));  // e[k]: bounce k + 1
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

  // sigma_1 / C: one-bundle first bounces rho T* E.
  std::vector<double> mean(n, 0.0), m2(n, 0.0);
  std::vector<glm::vec4> first;
  for (int b = 0; b < o.first_bounce; ++b) {
    bounce(emission, first, true);
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
  fit.sigma_ratio = std::sqrt(spread / area) / (level / area);
  std::nth_element(times.begin(), times.begin() + static_cast<long>(times.size() / 2), times.end());
  fit.t_iteration = times[times.size() / 2];
  fit.bundles = index;
  return fit;
}

}  // namespace sirad::model
