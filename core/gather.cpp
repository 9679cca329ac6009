// sirad: the final gather (see gather.h).
#include "core/gather.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <numbers>
#include <thread>

#include "core/camera.h"
#include "core/error.h"
#include "core/rays.h"

namespace sirad {

namespace {

// Purposes of the random streams (Rng's last key): one stream per pixel and purpose.
constexpr uint64_t kJitter = 1, kLight = 2, kGather = 3, kMore = 4;

// A gather ray that lands closer than this many patch sizes (sqrt(2 area)) of the patch it hits
// traces the light reflected there one bounce further instead of taking the solution.
constexpr double kNear = 2.0;

}  // namespace

struct FinalGather::Impl {
  const PatchMesh& mesh;
  GatherOptions options;
  std::vector<std::array<glm::vec3, 3>> corners;  // interpolated radiosity at each patch corner
  double offset;                                  // ray_offset: how far a ray leaves its surface
  RayScene rays;
  // The emitters: patch, and the running sum of their areas (area-proportional sampling).
  std::vector<uint32_t> emitter;
  std::vector<double> emitter_cdf;
  double emitter_area = 0.0;

  Impl(const PatchMesh& m, std::vector<std::array<glm::vec3, 3>> c, const GatherOptions& o)
      : mesh(m),
        options(o),
        corners(std::move(c)),
        offset(ray_offset(m)),
        rays(m, offset) {
    for (std::size_t j = 0; j < mesh.size(); ++j)
      if (mesh.emits(j)) {
        emitter.push_back(static_cast<uint32_t>(j));
        emitter_area += mesh.area[j];
        emitter_cdf.push_back(emitter_area);
      }
  }

  // The solution at point x of patch j: its corner radiosities, interpolated by x's barycentric
  // coordinates (clamped to the triangle).
  glm::dvec3 radiosity_at(uint32_t j, const glm::dvec3& x) const {
    const auto& p = mesh.patches[j];
    const glm::dvec3 a(mesh.vertices[p[0]]), b(mesh.vertices[p[1]]), c(mesh.vertices[p[2]]);
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double nn = glm::dot(n, n);
    double wb = nn > 0.0 ? glm::dot(glm::cross(x - a, c - a), n) / nn : 1.0 / 3.0;
    double wc = nn > 0.0 ? glm::dot(glm::cross(b - a, x - a), n) / nn : 1.0 / 3.0;
    wb = std::clamp(wb, 0.0, 1.0);
    wc = std::clamp(wc, 0.0, 1.0 - wb);
    const double wa = 1.0 - wb - wc;
    return wa * glm::dvec3(corners[j][0]) + wb * glm::dvec3(corners[j][1]) + wc * glm::dvec3(corners[j][2]);
  }

  // The emitter sample's pdf per solid angle seen from a point at distance^2 `r2` whose
  // direction meets the emitter's front at cosine `cos_light`.
  double light_pdf(double r2, double cos_light) const { return r2 / (cos_light * emitter_area); }

  // A shadow ray of the direct light and what it brings if nothing blocks it.
  struct ShadowRay {
    glm::dvec3 from, to, light;
  };

  // The emitter sample of the light reflected at point x (its ray leaving at `origin`, normal n)
  // from the unit-square point `light`: a point on an emitter, chosen by area, and its shadow
  // ray, with the light it brings before rho (MIS-weighted against the gather ray). The first
  // coordinate picks the emitter and, rescaled within its share, the point's first coordinate
  // on it: stratified points of the square stay stratified over all the emitters' area. False
  // where no ray is cast (no emitter, or one the point does not face or that does not face it).
  bool light_sample(const glm::dvec3& x, const glm::dvec3& origin, const glm::dvec3& n, const std::array<double, 2>& light,
                    ShadowRay& out) const {
    if (emitter.empty()) return false;
    const double pick = light[0] * emitter_area;
    const std::size_t k = std::min<std::size_t>(
        static_cast<std::size_t>(std::upper_bound(emitter_cdf.begin(), emitter_cdf.end(), pick) - emitter_cdf.begin()),
        emitter.size() - 1);
    const uint32_t e = emitter[k];
    const double below = k == 0 ? 0.0 : emitter_cdf[k - 1];
    const double s = std::clamp((pick - below) / (emitter_cdf[k] - below), 0.0, 1.0);
    const auto& p = mesh.patches[e];
    const glm::dvec3 y = on_triangle(glm::dvec3(mesh.vertices[p[0]]), glm::dvec3(mesh.vertices[p[1]]),
                                     glm::dvec3(mesh.vertices[p[2]]), s, light[1]);
    const glm::dvec3 ne(mesh.normal[e]);
    const glm::dvec3 d = y - x;
    const double r2 = glm::dot(d, d);
    if (!(r2 > 0.0)) return false;
    const glm::dvec3 w = d / std::sqrt(r2);
    const double cos_x = glm::dot(n, w), cos_y = -glm::dot(ne, w);
    if (!(cos_x > 0.0 && cos_y > 0.0)) return false;
    const double p_light = light_pdf(r2, cos_y), p_gather = cos_x / std::numbers::pi;
    // E cos_x / pi d(omega) / p_light, with MIS weight p_light / (p_light + p_gather).
    out = {origin, y + ne * offset, glm::dvec3(mesh.emission(e)) * (cos_x / std::numbers::pi / (p_light + p_gather))};
    return true;
  }

  // The gather ray of the light reflected at a point (its ray leaving at `origin`, normal n),
  // cosine-distributed from the unit-square point `gather`: the reflected light where it lands,
  // into `indirect`, and, if that is an emitter, its light weighted against the emitter sample,
  // into `direct` (both before rho). The solution where it lands, less its emission; where it
  // lands closer than kNear patch sizes (a corner, a contact: where the patch-wise solution is
  // least right), the light reflected there is traced once more instead, from `more`'s points
  // (at `depth` 0 only).
  void gathered(const glm::dvec3& origin, const glm::dvec3& n, const std::array<double, 2>& gather, Rng& more, int depth,
                glm::dvec3& direct, glm::dvec3& indirect, uint64_t& cast) const {
    const glm::dvec3 g = cosine_direction(n, gather[0], gather[1]);
    const auto [seen, s] = rays.seen_at(origin, g);
    ++cast;
    if (seen < 0) {
      indirect += glm::dvec3(mesh.background);
      return;
    }
    const uint32_t k = static_cast<uint32_t>(seen);
    const glm::dvec3 y = origin + g * s;
    const glm::dvec3 e(mesh.emission(k));
    const glm::dvec3 rho_k(mesh.reflectance(k));
    if (depth == 0 && s < kNear * std::sqrt(2.0 * mesh.area[k]) && rho_k != glm::dvec3(0.0)) {
      glm::dvec3 d(0.0), i(0.0);
      reflected(y, glm::dvec3(mesh.normal[k]), {more.uniform(), more.uniform()}, {more.uniform(), more.uniform()}, more, 1, d, i, cast);
      indirect += rho_k * (d + i);
    } else {
      indirect += radiosity_at(k, y) - e;
    }
    if (mesh.emits(k)) {
      const double cos_x = glm::dot(n, g), cos_y = -glm::dot(glm::dvec3(mesh.normal[k]), g);
      if (cos_x > 0.0 && cos_y > 0.0) {
        const double p_gather = cos_x / std::numbers::pi, p_light = light_pdf(s * s, cos_y);
        direct += e * (p_gather / (p_light + p_gather));
      }
    }
  }

  // The light reflected at point x (normal n) toward the viewer, before rho: one emitter sample
  // with its shadow ray (light_sample) and one gather ray (gathered), ray by ray.
  void reflected(const glm::dvec3& x, const glm::dvec3& n, const std::array<double, 2>& light, const std::array<double, 2>& gather,
                 Rng& more, int depth, glm::dvec3& direct, glm::dvec3& indirect, uint64_t& cast) const {
    const glm::dvec3 origin = x + n * offset;
    ShadowRay shadow;
    if (light_sample(x, origin, n, light, shadow)) {
      ++cast;
      if (!rays.blocked(shadow.from, shadow.to)) direct += shadow.light;
    }
    gathered(origin, n, gather, more, depth, direct, indirect, cast);
  }

  // Pixel (px, py) of the view `frame` into `out` at (ox, oy); returns the rays it cast. The
  // samples go in batches: the batch's primary rays (one origin, nearly one direction) traced
  // together as a stream, then their shadow rays (towards the same emitters) as another, then
  // each sample's gather ray (every way: one by one, a stream gains nothing); each sample's
  // light is added in sample order, as one sample at a time would.
  uint64_t pixel(const CameraFrame& frame, int px, int py, int ox, int oy, GatherPasses& out) const {
    const uint64_t index = static_cast<uint64_t>(py) * static_cast<uint64_t>(options.width) + static_cast<uint64_t>(px);
    // Each of the sample's three 2D choices (the position in the pixel, the emitter point, the
    // gather direction) stratified over the pixel's samples, the sets paired in random order
    // (in buffers of this thread's, kept from pixel to pixel).
    Rng jitter(options.seed, index, 0, kJitter), light(options.seed, index, 0, kLight), gather(options.seed, index, 0, kGather),
        more(options.seed, index, 0, kMore);
    thread_local std::vector<std::array<double, 2>> positions, lights, gathers;
    stratified_square(options.spp, jitter, positions);
    stratified_square(options.spp, light, lights);
    stratified_square(options.spp, gather, gathers);
    constexpr std::size_t kBatch = 64;
    struct Sample {
      glm::dvec3 seen;  // what the camera sees emitted (or the background)
      glm::dvec3 rho;   // 0: nothing reflected
      glm::dvec3 origin, normal;
      int shadow;       // index into the batch's shadow rays, or -1
    };
    std::array<glm::dvec3, kBatch> dirs;
    std::array<std::pair<int64_t, double>, kBatch> hits;
    std::array<Sample, kBatch> samples;
    std::array<glm::dvec3, kBatch> from, to, brings;
    std::array<bool, kBatch> blocked;
    glm::dvec3 direct(0.0), indirect(0.0);
    uint64_t cast = 0;
    const std::size_t spp = static_cast<std::size_t>(options.spp);
    for (std::size_t b0 = 0; b0 < spp; b0 += kBatch) {
      const std::size_t n = std::min(kBatch, spp - b0);
      for (std::size_t i = 0; i < n; ++i) dirs[i] = frame.direction(px + positions[b0 + i][0], py + positions[b0 + i][1]);
      rays.seen_at(frame.eye, dirs.data(), n, hits.data());
      cast += n;
      std::size_t shadows = 0;
      for (std::size_t i = 0; i < n; ++i) {
        Sample& a = samples[i];
        a.shadow = -1;
        a.rho = glm::dvec3(0.0);
        const auto [hit, t] = hits[i];
        if (hit < 0) {
          a.seen = glm::dvec3(mesh.background);
          continue;
        }
        const uint32_t j = static_cast<uint32_t>(hit);
        a.seen = glm::dvec3(mesh.emission(j));
        a.rho = glm::dvec3(mesh.reflectance(j));
        if (a.rho == glm::dvec3(0.0)) continue;
        const glm::dvec3 x = frame.eye + dirs[i] * t;
        a.normal = glm::dvec3(mesh.normal[j]);
        a.origin = x + a.normal * offset;
        ShadowRay r;
        if (light_sample(x, a.origin, a.normal, lights[b0 + i], r)) {
          a.shadow = static_cast<int>(shadows);
          from[shadows] = r.from, to[shadows] = r.to, brings[shadows] = r.light;
          ++shadows;
        }
      }
      if (shadows > 0) rays.blocked(from.data(), to.data(), shadows, blocked.data());
      cast += shadows;
      for (std::size_t i = 0; i < n; ++i) {
        const Sample& a = samples[i];
        direct += a.seen;
        if (a.rho == glm::dvec3(0.0)) continue;
        glm::dvec3 d(0.0), r(0.0);
        if (a.shadow >= 0 && !blocked[static_cast<std::size_t>(a.shadow)]) d += brings[static_cast<std::size_t>(a.shadow)];
        gathered(a.origin, a.normal, gathers[b0 + i], more, 0, d, r, cast);
        direct += a.rho * d;
        indirect += a.rho * r;
      }
    }
    const double w = 1.0 / options.spp;
    out.direct.at(ox, oy) = glm::vec3(direct * w);
    out.indirect.at(ox, oy) = glm::vec3(indirect * w);
    out.combined.at(ox, oy) = glm::vec3((direct + indirect) * w);
    return cast;
  }
};

namespace {

void check_options(const GatherOptions& options) {
  if (options.spp < 1 || options.spp > 65536) fail("final gather: {} samples per pixel (1..65536)", options.spp);
  if (options.width < 1 || options.height < 1 || options.width > kMaxImageSide || options.height > kMaxImageSide)
    fail("final gather: image {}x{} (1 to {} a side)", options.width, options.height, kMaxImageSide);
  if (options.threads < 0) fail("final gather: {} threads", options.threads);
}

}  // namespace

FinalGather::FinalGather(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, const GatherOptions& options) {
  check_options(options);
  if (radiosity.size() != mesh.size()) fail("final gather: {} radiosity values for {} patches", radiosity.size(), mesh.size());
  impl_ = std::make_unique<Impl>(mesh, corner_radiosity(mesh, radiosity), options);
}

FinalGather::FinalGather(const PatchMesh& mesh, std::vector<std::array<glm::vec3, 3>> corners, const GatherOptions& options) {
  check_options(options);
  if (corners.size() != mesh.size()) fail("final gather: {} patches' corner values for {} patches", corners.size(), mesh.size());
  impl_ = std::make_unique<Impl>(mesh, std::move(corners), options);
}

FinalGather::~FinalGather() = default;

int GatherOptions::thread_count() const {
  return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

GatherPasses GatherPasses::of_size(int width, int height) {
  GatherPasses p;
  for (Image* image : {&p.direct, &p.indirect, &p.combined}) {
    image->width = width;
    image->height = height;
    image->pixels.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), glm::vec3(0.0f));
  }
  return p;
}

const GatherOptions& FinalGather::options() const { return impl_->options; }

GatherPasses FinalGather::render(const Camera& camera, int x0, int y0, int x1, int y1, const std::function<void()>& between) const {
  const GatherOptions& o = impl_->options;
  if (x0 < 0 || y0 < 0 || x1 > o.width || y1 > o.height || x0 > x1 || y0 > y1)
    fail("final gather: region [{}, {}) x [{}, {}) is not within the {}x{} image", x0, x1, y0, y1, o.width, o.height);
  const CameraFrame frame = camera_frame(camera, o.width, o.height, "final gather");
  GatherPasses out = GatherPasses::of_size(x1 - x0, y1 - y0);
  const unsigned threads = std::min<unsigned>(static_cast<unsigned>(o.thread_count()),
                                              static_cast<unsigned>(std::max(1, y1 - y0)));
  std::atomic<int> next_row{y0};
  std::vector<uint64_t> cast(threads, 0);
  auto rows = [&](unsigned t) {  // whole rows each: no pixel is written by two threads
    for (int y; (y = next_row.fetch_add(1)) < y1;) {
      for (int x = x0; x < x1; ++x) cast[t] += impl_->pixel(frame, x, y, x - x0, y - y0, out);
      if (t == 0 && between) between();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(rows, t);
  rows(0);
  for (auto& th : pool) th.join();
  for (uint64_t c : cast) out.rays += c;
  return out;
}

GatherPasses FinalGather::render(const Camera& camera) const {
  return render(camera, 0, 0, impl_->options.width, impl_->options.height);
}

}  // namespace sirad
