// sirad tests: the bundle transport against the reference solver, over regions of a scene.
//
// If one random transport T* is unbiased for the reference's model, E[E + T* B] = E + T B for
// any input B, and the reference solves B_ref = E + T B_ref up to its own error e, so
// E[E + T* B_ref] - B_ref = -(I - T) e, whose aggregate is below the reference's (A_i (T e)_i
// sums to sum_j A_j e_j g_j with g_j = sum_i rho_i F_ji in [0, rho_max]). This isolates the
// kernel from the chain's variance (which multiplies it by about (1 + rho) / (1 - rho)) and lets
// directions be stratified: G replicates, each an m x m stratified set of directions (equal-area
// map of the sphere, own jitter), replicate g taking the reference's batch solution B_g as input.
// The replicates are independent (own directions, own reference batch), so for a region R
//     d_g = sum_(j in R) A_j (E + T*_g B_g - B_g)_j / sum_(j in R) A_j B_ref,j   (channels summed)
// has mean d and SE = sd(d_g) / sqrt(G), with both the bundles' and the reference's noise in it.
#pragma once
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "engine/bundle.h"
#include "scene/mesh.h"
#include "solver/reference.h"

namespace sirad::test {

// A set of patches of a mesh: in[j] says whether patch j belongs to it.
struct Region {
  std::string name;
  std::vector<char> in;
};

// The non-emitting patches (all of them where every patch emits: the furnace).
inline Region non_emitting(const PatchMesh& mesh) {
  bool all = true;
  for (std::size_t j = 0; j < mesh.size() && all; ++j) all = mesh.emits(j);
  Region r{"all", std::vector<char>(mesh.size(), 0)};
  for (std::size_t j = 0; j < mesh.size(); ++j) r.in[j] = all || !mesh.emits(j);
  return r;
}

// Mean and sample standard deviation.
inline std::pair<double, double> mean_sd(const std::vector<double>& v) {
  double m = 0.0, q = 0.0;
  for (double x : v) m += x / static_cast<double>(v.size());
  for (double x : v) q += (x - m) * (x - m) / static_cast<double>(v.size() - 1);
  return {m, std::sqrt(q)};
}

struct Agreement {
  std::string region;
  double d = 0.0;   // relative difference of E + T* B_ref from B_ref over the region
  double se = 0.0;  // its standard error
  glm::dvec3 channel{0.0};  // per channel (mean over replicates of the ratio - 1)
  double reference = 0.0;   // the region's area-weighted mean of the reference (channels summed)
};

// E + T* B_ref against B_ref over each region (see the banner): m x m stratified directions per
// reference batch, on `engine` with `grid` lines per side.
inline std::vector<Agreement> transport_agreement(const PatchMesh& mesh, const ReferenceSolution& ref,
                                                  BundleEngine& engine, int grid, int m,
                                                  const std::vector<Region>& regions) {
  const double two_delta = 2.0 * cell_area(mesh, grid);
  const int G = ref.batches;
  std::vector<std::vector<double>> d(regions.size());
  std::vector<glm::dvec3> channel(regions.size(), glm::dvec3(0.0));
  BundleResult result;
  std::vector<glm::vec4> input(mesh.size());
  auto sum_over = [&](const Region& r, auto value) {
    glm::dvec3 s(0.0);
    for (std::size_t j = 0; j < mesh.size(); ++j)
      if (r.in[j]) s += static_cast<double>(mesh.area[j]) * glm::dvec3(value(j));
    return s;
  };
  for (int g = 0; g < G; ++g) {
    const auto& B = ref.batch_radiosity[static_cast<std::size_t>(g)];
    for (std::size_t j = 0; j < mesh.size(); ++j) input[j] = glm::vec4(glm::vec3(B[j]), 0.0f);
    std::vector<glm::dvec3> sum(mesh.size(), glm::dvec3(0.0));
    for (int k = 0; k < m * m; ++k) {
      // Stratum (k / m, k % m) of the equal-area map z = 1 - 2s, phi = 2 pi t, jittered.
      uint64_t index = static_cast<uint64_t>(g) * static_cast<uint64_t>(m * m) + static_cast<uint64_t>(k);
      SiradBundle b = make_bundle(mesh, grid, 77, index);
      BundleDraw jitter = draw_bundle(78, index);
      double s = (k / m + jitter.jitter_x) / m, t = (k % m + jitter.jitter_y) / m;
      double z = 1.0 - 2.0 * s, rr = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = 2.0 * std::numbers::pi * t;
      glm::dvec3 w(rr * std::cos(phi), rr * std::sin(phi), z);
      double sign = std::copysign(1.0, w.z), a = -1.0 / (sign + w.z), bb = w.x * w.y * a;
      glm::dvec3 u(1.0 + sign * w.x * w.x * a, sign * bb, -sign * w.x), v(bb, sign + w.y * w.y * a, -w.y);
      for (int q = 0; q < 3; ++q) {
        b.u[q] = static_cast<float>(u[q]);
        b.v[q] = static_cast<float>(v[q]);
        b.w[q] = static_cast<float>(w[q]);
      }
      engine.run(b, input, result);
      for (std::size_t j = 0; j < mesh.size(); ++j) sum[j] += glm::dvec3(result.gathered[j]);
    }
    for (std::size_t r = 0; r < regions.size(); ++r) {
      glm::dvec3 x = sum_over(regions[r], [&](std::size_t j) {
        return glm::dvec3(mesh.emission(j)) +
               glm::dvec3(mesh.reflectance(j)) * (two_delta / mesh.area[j]) * sum[j] / static_cast<double>(m * m);
      });
      glm::dvec3 y = sum_over(regions[r], [&](std::size_t j) { return B[j]; });
      glm::dvec3 pooled = sum_over(regions[r], [&](std::size_t j) { return ref.radiosity[j]; });
      d[r].push_back((x.x + x.y + x.z - y.x - y.y - y.z) / (pooled.x + pooled.y + pooled.z));
      channel[r] += (x / y - 1.0) / static_cast<double>(G);
    }
  }
  std::vector<Agreement> out;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    auto [md, sd] = mean_sd(d[r]);
    double area = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j)
      if (regions[r].in[j]) area += mesh.area[j];
    glm::dvec3 pooled = sum_over(regions[r], [&](std::size_t j) { return ref.radiosity[j]; });
    out.push_back({regions[r].name, md, sd / std::sqrt(static_cast<double>(G)), channel[r],
                   (pooled.x + pooled.y + pooled.z) / area});
  }
  return out;
}

}  // namespace sirad::test
