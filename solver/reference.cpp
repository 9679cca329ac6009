// sirad: the independent reference solver (see reference.h): Embree 3 ray casting, the exact
// point-to-polygon form factor for direct light with visibility as a control variate, batches
// for the standard error, Gauss-Seidel for the linear system.
//
// Bias. Each batch solution is a nonlinear function of its estimated matrix F_b; rows of F_b
// come from independent rays of different patches, so a product F_ij F_jk ... over a light path
// is unbiased unless the path uses the same row entry twice (i -> j -> ... -> i -> j), where
// E[F_ij^2] = F_ij^2 + Var(F_ij), Var(F_ij) ~ F_ij / n_b (n_b rays per patch and batch). The
// shortest such path contributes rho^3 F_ij F_ji F_ij B_j, so the relative bias is at most about
// rho^3 max_j F_ji / n_b: below 1e-3 * F_ji at n_b = 256, i.e. far below the standard error
// (which is O(1 / sqrt(n_b R))). The direct part is linear in its samples: unbiased. Hence the
// mean of the batch solutions is used as the estimate (its spread is exactly what the standard
// error describes); its O(R / n) bias is negligible.
#include "solver/reference.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>

#include <glm/geometric.hpp>

#include "scene/emitters.h"
#include "scene/rays.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/parallel.h"

namespace sirad {
namespace {

using glm::dvec3;

// The form factor from a point x with unit normal n to the part of the polygon p[0..count)
// in front of x's tangent plane (n . (y - x) > 0): Lambert's contour formula,
//   F = (1 / 2 pi) |sum_k theta_k n . g_k|,
// theta_k the angle p_k, p_k+1 subtend at x and g_k the unit normal of the plane through x and
// that edge. The polygon is first clipped against the tangent plane (Sutherland-Hodgman); the
// clipped polygon lies in the closed upper hemisphere, where the integrand cos(theta_x) >= 0,
// so the absolute value of the signed sum is the form factor whatever the winding.
double polygon_form_factor(const dvec3& x, const dvec3& n, const dvec3* p, int count) {
  dvec3 clipped[8];
  int m = 0;
  for (int k = 0; k < count; ++k) {
    const dvec3 &a = p[k], &b = p[(k + 1) % count];
    double ha = glm::dot(n, a - x), hb = glm::dot(n, b - x);
    if (ha > 0.0) clipped[m++] = a - x;
    if ((ha > 0.0) != (hb > 0.0)) {
      dvec3 q = a + (b - a) * (ha / (ha - hb)) - x;
      q -= n * glm::dot(n, q);  // exactly in the plane despite rounding
      clipped[m++] = q;
    }
  }
  if (m < 3) return 0.0;
  double sum = 0.0;
  for (int k = 0; k < m; ++k) {
    dvec3 a = clipped[k], b = clipped[(k + 1) % m];
    double la = glm::length(a), lb = glm::length(b);
    if (la <= 0.0 || lb <= 0.0) continue;
    a /= la;
    b /= lb;
    dvec3 c = glm::cross(a, b);
    double lc = glm::length(c);
    if (lc <= 0.0) continue;
    sum += std::atan2(lc, glm::dot(a, b)) * glm::dot(n, c) / lc;
  }
  return std::abs(sum) / (2.0 * std::numbers::pi);
}

// One batch's system: sparse rows of F (patch, weight), the background weight, the direct part.
struct Row {
  std::vector<std::pair<uint32_t, float>> entries;
  float background = 0.0f;
};

constexpr uint32_t kBackground = 0xffffffffu;

// Segments per patch and emitter that decide how the direct light from that emitter is estimated.
constexpr int kPilot = 8;

// What one worker reuses from patch to patch, and the rays it cast.
struct Scratch {
  std::vector<std::array<double, 2>> pts, dirs, ys;
  std::vector<signed char> hidden;
  std::vector<uint32_t> hits;
  uint64_t cast = 0;
};

// The batches' systems, sampled per patch: its row of F and its direct light in each batch.
class Sampler {
 public:
  Sampler(const PatchMesh& mesh, const ReferenceOptions& o, const std::vector<Light>& emitters, const RayScene& rays, double eps)
      : mesh_(mesh), o_(o), emitters_(emitters), rays_(rays), eps_(eps), rays_b_(o.rays_per_patch / o.batches),
        points_b_(o.light_samples / o.batches) {}

  // Patch i's row and direct light in every batch, into rows[batch][i] and direct[batch][i].
  void patch(std::size_t i, Scratch& s, std::vector<std::vector<Row>>& rows, std::vector<std::vector<dvec3>>& direct) const {
    const auto& tri = mesh_.patches[i];
    const Patch p{dvec3(mesh_.vertices[tri[0]]), dvec3(mesh_.vertices[tri[1]]), dvec3(mesh_.vertices[tri[2]]), dvec3(mesh_.normal[i]),
                  dvec3(mesh_.reflectance(i))};
    if (p.rho != dvec3(0.0)) pilot(i, p, s);
    for (int bt = 0; bt < o_.batches; ++bt) {
      indirect_row(i, bt, p, s, rows[static_cast<std::size_t>(bt)][i]);
      if (p.rho == dvec3(0.0) || emitters_.empty()) continue;
      direct[static_cast<std::size_t>(bt)][i] = p.rho * direct_light(i, bt, p, s);
    }
  }

 private:
  struct Patch {
    dvec3 a, b, c, nx, rho;
  };

  // Per emitter: -1 the patch lies wholly behind it, 1 it mostly does not see it (fewer than
  // half of kPilot segments from points on the patch to points on it are clear), 0 else.
  // The pilot has its own random stream, so each batch's estimate stays unbiased whichever
  // way it decides.
  void pilot(std::size_t i, const Patch& p, Scratch& s) const {
    const auto& [a, b, c, nx, rho] = p;
    s.hidden.assign(emitters_.size(), 0);
    for (std::size_t l = 0; l < emitters_.size(); ++l) {
      const Light& L = emitters_[l];
      if (glm::dot(L.normal, (a + b + c) / 3.0 - L.p[0]) <= 0.0 && glm::dot(L.normal, a - L.p[0]) <= 0.0 &&
          glm::dot(L.normal, b - L.p[0]) <= 0.0 && glm::dot(L.normal, c - L.p[0]) <= 0.0) {
        s.hidden[l] = -1;  // L shows the patch only its back
        continue;
      }
      Rng prng(o_.seed, i, l, 3);
      stratified_square(kPilot, prng, s.pts);
      stratified_square(kPilot, prng, s.ys);
      int clear = 0;
      for (int k = 0; k < kPilot; ++k) {
        dvec3 x = on_triangle(a, b, c, s.pts[static_cast<std::size_t>(k)][0], s.pts[static_cast<std::size_t>(k)][1]);
        dvec3 y = L.at(s.ys[static_cast<std::size_t>(k)][0], s.ys[static_cast<std::size_t>(k)][1]);
        if (glm::dot(nx, y - x) > 0.0 && glm::dot(L.normal, x - y) > 0.0 && !rays_.blocked(x + nx * eps_, y + L.normal * eps_))
          ++clear;
      }
      s.cast += kPilot;
      s.hidden[l] = 2 * clear < kPilot ? 1 : 0;
    }
  }

  // Indirect: cosine-distributed rays from stratified points; the hit counts / n_b are the row
  // of F (emitters included: they carry their reflected part Y here).
  void indirect_row(std::size_t i, int bt, const Patch& p, Scratch& s, Row& row) const {
    const auto& [a, b, c, nx, rho] = p;
    Rng rng(o_.seed, i, static_cast<uint64_t>(bt), 1);
    stratified_square(rays_b_, rng, s.pts);
    stratified_square(rays_b_, rng, s.dirs);
    s.hits.clear();
    for (int k = 0; k < rays_b_; ++k) {
      dvec3 x = on_triangle(a, b, c, s.pts[static_cast<std::size_t>(k)][0], s.pts[static_cast<std::size_t>(k)][1]);
      dvec3 d = cosine_direction(nx, s.dirs[static_cast<std::size_t>(k)][0], s.dirs[static_cast<std::size_t>(k)][1]);
      int64_t j = rays_.covered(static_cast<uint32_t>(i), x) ? -1 : rays_.seen(x + nx * eps_, d);
      s.hits.push_back(j >= 0 ? static_cast<uint32_t>(j) : kBackground);
    }
    s.cast += static_cast<uint64_t>(rays_b_);
    std::sort(s.hits.begin(), s.hits.end());
    row.entries.clear();
    const float w = 1.0f / static_cast<float>(rays_b_);
    for (std::size_t k = 0; k < s.hits.size();) {
      std::size_t e = k;
      while (e < s.hits.size() && s.hits[e] == s.hits[k]) ++e;
      float weight = w * static_cast<float>(e - k);
      if (s.hits[k] == kBackground) row.background = weight;
      else row.entries.emplace_back(s.hits[k], weight);
      k = e;
    }
  }

  // Direct, per emitting input triangle L (scene/emitters.h), y stratified on L, one per point
  // and L. Where the patch sees L (the pilot): the exact unoccluded form factor minus the
  // visibility control variate A_L K(x, y) (1 - V(x, y)); E[A_L K (1 - V)] = F_analytic -
  // F_visible, so the estimate is unbiased, and exact wherever nothing occludes. Where it mostly
  // does not (a box lamp's lit inside, seen from the ceiling 1 cm over its lid): A_L K V alone,
  // also unbiased, and 0 where L is wholly hidden, where the control variate would subtract K's
  // sharp peak near L from its integral. The irradiance over pi, before the reflectance.
  dvec3 direct_light(std::size_t i, int bt, const Patch& p, Scratch& s) const {
    const auto& [a, b, c, nx, rho] = p;
    Rng lrng(o_.seed, i, static_cast<uint64_t>(bt), 2);
    stratified_square(points_b_, lrng, s.pts);
    dvec3 sum(0.0);
    for (std::size_t l = 0; l < emitters_.size(); ++l) {
      const Light& L = emitters_[l];
      if (s.hidden[l] < 0) continue;
      const bool plain = s.hidden[l] > 0;
      stratified_square(points_b_, lrng, s.ys);
      double f = 0.0;
      for (int k = 0; k < points_b_; ++k) {
        dvec3 x = on_triangle(a, b, c, s.pts[static_cast<std::size_t>(k)][0], s.pts[static_cast<std::size_t>(k)][1]);
        const double ahead = glm::dot(L.normal, x - L.p[0]);
        if (ahead <= 0.0) continue;  // behind L (or in its plane)
        // A point within eps of L's plane and parallel to it receives nothing from L, though
        // rounding may put it a hair in front: on L's back (its twin, the other side of one
        // two-sided face) L faces away; facing the way L faces (a ceiling around a flush
        // lamp) L lies in its tangent plane, where the contour formula sees L's corners a
        // hair above or below that plane and gives anything from 0 to 1.
        if (std::abs(glm::dot(L.normal, nx)) > 0.9999 && ahead <= eps_) continue;
        if (rays_.covered(static_cast<uint32_t>(i), x)) continue;  // under a coincident face
        double fa = polygon_form_factor(x, nx, L.p.data(), L.corners);
        if (fa <= 0.0) continue;
        dvec3 y = L.at(s.ys[static_cast<std::size_t>(k)][0], s.ys[static_cast<std::size_t>(k)][1]);
        dvec3 r = y - x;
        double r2 = glm::dot(r, r), cx = glm::dot(nx, r), cy = -glm::dot(L.normal, r);
        if (!(cx > 0.0 && cy > 0.0 && r2 > 0.0)) {
          if (!plain) f += fa;
          continue;
        }
        ++s.cast;
        const bool blocked = rays_.blocked(x + nx * eps_, y + L.normal * eps_);
        const double k_y = L.area * cx * cy / (std::numbers::pi * r2 * r2);
        if (plain) f += blocked ? 0.0 : k_y;
        else f += blocked ? fa - k_y : fa;
      }
      sum += L.emission * (f / points_b_);
    }
    return sum;
  }

  const PatchMesh& mesh_;
  const ReferenceOptions& o_;
  const std::vector<Light>& emitters_;
  const RayScene& rays_;
  const double eps_;
  const int rays_b_, points_b_;
};

}  // namespace

ReferenceSolution solve_reference(const PatchMesh& mesh, const ReferenceOptions& o) {
  if (o.batches < 1) fail("reference: batches must be at least 1 (got {})", o.batches);
  if (o.rays_per_patch < o.batches) fail("reference: rays per patch ({}) below the batch count ({})", o.rays_per_patch, o.batches);
  if (o.light_samples < o.batches) fail("reference: light samples ({}) below the batch count ({})", o.light_samples, o.batches);
  if (o.threads < 0) fail("reference: threads must be >= 0 (got {})", o.threads);
  if (mesh.size() == 0) fail("reference: empty mesh");
  auto start = std::chrono::steady_clock::now();

  const std::size_t n = mesh.size();
  const int R = o.batches;
  const std::vector<Light> emitters = input_triangle_lights(mesh);
  // Ray origins leave the surface along its normal by eps: a few hundred float ulps of the
  // scene's coordinates, so a ray never re-hits its own patch or the back-to-back twin of a
  // thin wall, and far below any patch size (its effect on a form factor is O(eps / distance)).
  // Faces closer than eps are one place (the coincident-face rule, RayScene): at least the
  // bundles' depth tie (1e-5 of the scene's radius), so the two agree on every gap a scene
  // means to be one, and far below any gap meant to let light through.
  const double eps = ray_offset(mesh);
  RayScene rays(mesh, eps);

  std::vector<std::vector<Row>> rows(static_cast<std::size_t>(R), std::vector<Row>(n));
  std::vector<std::vector<dvec3>> direct(static_cast<std::size_t>(R), std::vector<dvec3>(n, dvec3(0.0)));
  const unsigned threads = worker_threads(o.threads);
  std::vector<Scratch> scratch(threads);
  const Sampler sampler(mesh, o, emitters, rays, eps);
  parallel_for(n, 16, threads, [&](std::size_t first, std::size_t last, unsigned worker) {
    for (std::size_t i = first; i < last; ++i) sampler.patch(i, scratch[worker], rows, direct);
  });
  uint64_t cast = 0;
  for (const Scratch& w : scratch) cast += w.cast;

  // Solve each batch: Y = D + rho (F Y + F_bg background), Gauss-Seidel until the largest
  // change is below 1e-12 of the largest value (the contraction is at most rho_max < 1 per sweep
  // in a closed scene; with rho = 1 somewhere the system may not converge: capped).
  ReferenceSolution s;
  s.batches = R;
  s.batch_radiosity.assign(static_cast<std::size_t>(R), std::vector<dvec3>(n));
  std::vector<int> iterations(static_cast<std::size_t>(R), 0);
  std::vector<char> converged(static_cast<std::size_t>(R), 1);
  constexpr int kMaxSweeps = 20000;
  parallel_for(static_cast<std::size_t>(R), 1, threads, [&](std::size_t batch, std::size_t, unsigned) {
    const int bt = static_cast<int>(batch);
    const auto& F = rows[static_cast<std::size_t>(bt)];
    const auto& D = direct[static_cast<std::size_t>(bt)];
    std::vector<dvec3> y = D;
    dvec3 bg(mesh.background);
    int sweep = 0;
    for (; sweep < kMaxSweeps; ++sweep) {
      double change = 0.0, top = 1e-300;
      for (std::size_t i = 0; i < n; ++i) {
        dvec3 g = bg * static_cast<double>(F[i].background);
        for (const auto& [j, w] : F[i].entries) g += y[j] * static_cast<double>(w);
        dvec3 v = D[i] + dvec3(mesh.reflectance(i)) * g;
        dvec3 dv = glm::abs(v - y[i]);
        change = std::max({change, dv.x, dv.y, dv.z});
        top = std::max({top, v.x, v.y, v.z});
        y[i] = v;
      }
      if (change <= 1e-12 * top) break;
    }
    iterations[static_cast<std::size_t>(bt)] = sweep + 1;
    if (sweep == kMaxSweeps) converged[static_cast<std::size_t>(bt)] = 0;
    auto& out = s.batch_radiosity[static_cast<std::size_t>(bt)];
    for (std::size_t i = 0; i < n; ++i) out[i] = dvec3(mesh.emission(i)) + y[i];
  });

  auto mean_se = [&](auto value, std::vector<dvec3>& mean, std::vector<dvec3>& se) {
    mean.assign(n, dvec3(0.0));
    se.assign(n, dvec3(0.0));
    for (std::size_t i = 0; i < n; ++i) {
      dvec3 m(0.0), q(0.0);
      for (int bt = 0; bt < R; ++bt) m += value(bt, i);
      m /= static_cast<double>(R);
      for (int bt = 0; bt < R; ++bt) {
        dvec3 d = value(bt, i) - m;
        q += d * d;
      }
      mean[i] = m;
      se[i] = R > 1 ? glm::sqrt(q / static_cast<double>(R - 1) / static_cast<double>(R)) : dvec3(0.0);
    }
  };
  mean_se([&](int bt, std::size_t i) { return s.batch_radiosity[static_cast<std::size_t>(bt)][i]; }, s.radiosity, s.radiosity_se);
  mean_se([&](int bt, std::size_t i) { return direct[static_cast<std::size_t>(bt)][i]; }, s.direct, s.direct_se);
  s.iterations = *std::max_element(iterations.begin(), iterations.end());
  s.converged = std::all_of(converged.begin(), converged.end(), [](char c) { return c != 0; });
  s.rays = cast;
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return s;
}

double mean_relative_se(const PatchMesh& mesh, const ReferenceSolution& s) {
  double num = 0.0, den = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (mesh.emits(j)) continue;
    num += mesh.area[j] * glm::length(s.radiosity_se[j]);
    den += mesh.area[j] * glm::length(s.radiosity[j]);
  }
  return den > 0.0 ? num / den : 0.0;
}

namespace {
constexpr const char* kMagic = "# sirad reference v1";
constexpr const char* kColumns = "patch,B_r,B_g,B_b,Bse_r,Bse_g,Bse_b,D_r,D_g,D_b,Dse_r,Dse_g,Dse_b";
}  // namespace

void write_reference(const std::string& path, const PatchMesh& mesh, const ReferenceSolution& s,
                     const ReferenceOptions& o) {
  AtomicFile file(path);
  std::string text = fmt::format("{}\n# mesh_hash {} patches {} rays_per_patch {} light_samples {} batches {} seed {}\n{}\n",
                                 kMagic, mesh.hash, mesh.size(), o.rays_per_patch, o.light_samples, o.batches, o.seed,
                                 kColumns);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    text += fmt::format("{}", j);
    for (const auto* v : {&s.radiosity[j], &s.radiosity_se[j], &s.direct[j], &s.direct_se[j]})
      text += fmt::format(",{},{},{}", v->x, v->y, v->z);  // shortest round-trip form
    text += '\n';
    if (text.size() > (1u << 20)) {
      file.write(text.data(), text.size());
      text.clear();
    }
  }
  file.write(text.data(), text.size());
  file.commit();
}

ReferenceSolution read_reference(const std::string& path, const PatchMesh& mesh) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open: {}", path, std::strerror(errno));
  std::string line;
  std::size_t number = 0;
  auto next_line = [&](const char* what) {
    if (!std::getline(in, line)) fail("{}:{}: file ends early (expected {})", path, number + 1, what);
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
  };
  next_line("the header");
  if (line != kMagic) fail("{}:{}: not a sirad reference file (expected '{}')", path, number, kMagic);
  next_line("the mesh hash line");
  std::istringstream hs(line);
  std::string hash_key, hash, patches_key;
  std::size_t patches = 0;
  if (!(hs >> std::ws) || hs.get() != '#' || !(hs >> hash_key >> hash >> patches_key >> patches) || hash_key != "mesh_hash" ||
      patches_key != "patches")
    fail("{}:{}: malformed header (expected '# mesh_hash HASH patches N ...')", path, number);
  if (hash != mesh.hash) fail("{}:{}: computed for mesh {}, not this mesh ({})", path, number, hash, mesh.hash);
  if (patches != mesh.size()) fail("{}:{}: {} patches, the mesh has {}", path, number, patches, mesh.size());
  next_line("the column names");
  if (line != kColumns) fail("{}:{}: unexpected columns (expected '{}')", path, number, kColumns);
  ReferenceSolution s;
  const std::size_t n = mesh.size();
  s.radiosity.resize(n);
  s.radiosity_se.resize(n);
  s.direct.resize(n);
  s.direct_se.resize(n);
  for (std::size_t j = 0; j < n; ++j) {
    next_line("a patch line");
    double v[13];
    const char* p = line.data();
    const char* end = line.data() + line.size();
    for (int k = 0; k < 13; ++k) {
      if (k > 0) {
        if (p == end || *p != ',') fail("{}:{}: expected 13 comma-separated fields", path, number);
        ++p;
      }
      auto [q, ec] = std::from_chars(p, end, v[k]);
      if (ec != std::errc() || q == p) fail("{}:{}: field {} is not a number", path, number, k + 1);
      if (!std::isfinite(v[k])) fail("{}:{}: field {} is not finite", path, number, k + 1);
      p = q;
    }
    if (p != end) fail("{}:{}: trailing text after 13 fields", path, number);
    if (v[0] != static_cast<double>(j)) fail("{}:{}: patch {} where {} was expected", path, number, v[0], j);
    for (int k : {4, 5, 6, 10, 11, 12})  // standard errors (an estimate itself may dip below 0)
      if (v[k] < 0.0) fail("{}:{}: field {} (a standard error) is negative", path, number, k + 1);
    s.radiosity[j] = dvec3(v[1], v[2], v[3]);
    s.radiosity_se[j] = dvec3(v[4], v[5], v[6]);
    s.direct[j] = dvec3(v[7], v[8], v[9]);
    s.direct_se[j] = dvec3(v[10], v[11], v[12]);
  }
  if (std::getline(in, line) && !line.empty()) fail("{}:{}: unexpected text after the last patch", path, number + 1);
  return s;
}

}  // namespace sirad
