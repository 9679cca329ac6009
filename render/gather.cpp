// sirad: the final gather (see gather.h).
#include "render/gather.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <numbers>
#include <span>

#include "render/record_store.h"
#include "scene/camera.h"
#include "scene/emitters.h"
#include "scene/rays.h"
#include "util/error.h"
#include "util/parallel.h"

namespace sirad {

namespace {

// Purposes of the random streams (Rng's last key): one stream per pixel and purpose.
constexpr uint64_t kJitter = 1, kLight = 2, kGather = 3, kMore = 4, kRecordGather = 5, kRecordMore = 6;

// A gather ray that lands closer than this many patch sizes (sqrt(2 area)) of the patch it hits
// traces the light reflected there one bounce further instead of taking the solution: near a
// corner the solution's patch is as large as the distance, so its value is the wrong one there.
// Further out a bounce adds more noise than it removes bias (bench/RESULTS.md, "Images against
// Cycles, fifth session", has the sweep over this distance).
constexpr double kNear = 4.0;

// The irradiance cache (gather.h): records at the raster points of a grid kCacheSpacing pixels
// apart; a block of the grid is split in four, down to kCacheLeast pixels, while its four corner
// records
//   - are not all on reflecting surfaces, or
//   - face ways more than acos(kCacheCos) apart, or lie off each other's planes by more than
//     kCachePlane of their distance, or
//   - lie further apart than kCacheWard of the least distance any of their rays went (Ward's
//     criterion, with the least distance as Tabellion and Lamorlette take it: the indirect light
//     changes over the distance to what reflects it; the harmonic mean misses a small bright
//     surface among rays that leave the scene).
// Blocks of kCacheAny pixels or fewer are taken at any distance (near walls the criterion would
// split blocks down to kCacheLeast for a light that changes there nearly linearly, twice the
// records for no gain in error), if their corners
// of one surface see each other (a thin wall between two corners on one floor; else split, and
// at kCacheLeast no cache). A sample takes
// the corners of its pixel's block if its own point faces their way and lies in their planes
// (the same measures); in a block of kCacheLeast pixels whose corners are not one surface (an
// edge), the corners on the sample's own; where there are none, it traces its own gather ray.
// Where a block's records met emitters with more than kCacheMis of their rays, its samples keep
// a gather ray for the direct light's MIS.
// Nor is a block whose corners' indirect light differs by more than kCacheContrast times, at any
// size: beside a lamp hung just under a ceiling, the light that leaves the gap falls off within
// a few centimetres, convex, and a bilinear interpolation between a bright corner and a dim one
// lies above it over the whole block (bench/RESULTS.md, "The cache beside a lamp", has the sweep).
constexpr int kCacheSpacing = 16, kCacheAny = 4, kCacheLeast = 2;
constexpr double kCacheCos = 0.98, kCachePlane = 0.05, kCacheWard = 0.25, kCacheMis = 0.02, kCacheContrast = 1.25;

// From kEdgeSpp samples per pixel on, an edge's pixels (a block of kCacheLeast pixels whose
// corners are not one surface) take nothing from the cache: their samples gather for themselves,
// as do all samples that take nothing from it, with kEdgeRays gather rays each. The corners of
// the sample's own surface lie up to 2 pixels away, and towards a concave edge the indirect
// light changes fast, so taking them biases an edge's pixels. One gather ray a sample there is
// noisier than the cache's pixels by far; kEdgeRays make them as quiet. Below kEdgeSpp the
// noise they add outweighs the bias they remove, and edges' samples take the corners of their
// own surface (bench/RESULTS.md, "Images against Cycles, sixth session", has the figures).
constexpr int kEdgeSpp = 256, kEdgeRays = 8;

}  // namespace

struct FinalGather::Impl {
  const PatchMesh& mesh;
  GatherOptions options;
  std::vector<std::array<glm::vec3, 3>> corners;  // interpolated radiosity at each patch corner
  double offset;                                  // ray_offset: how far a ray leaves its surface
  RayScene rays;
  // The emitters as lights (scene/emitters.h), each patch's light (-1: none), and the lights'
  // area-proportional choice (a Choice's cumulative probabilities).
  std::vector<Light> lights;
  std::vector<int32_t> light_of;
  std::vector<uint8_t> overlapping;  // per object: whether any of its patches shares a place (covered)
  std::vector<double> by_area;
  // The cache records of the last view rendered (a view's tiles, rendered one after another,
  // share them).
  mutable std::mutex views_mutex;
  mutable std::shared_ptr<RecordStore> view_records;
  mutable Camera view_camera;

  // The records of the view from `camera` (null without a cache).
  std::shared_ptr<RecordStore> records(const Camera& camera) const {
    if (!options.cache) return nullptr;
    std::lock_guard lock(views_mutex);
    const bool same = view_records && view_camera.eye == camera.eye && view_camera.look_at == camera.look_at &&
                      view_camera.up == camera.up && view_camera.vfov_deg == camera.vfov_deg;
    if (!same) {
      view_records = std::make_shared<RecordStore>();
      view_camera = camera;
    }
    return view_records;
  }

  Impl(const PatchMesh& m, std::vector<std::array<glm::vec3, 3>> c, const GatherOptions& o)
      : mesh(m),
        options(o),
        corners(std::move(c)),
        offset(ray_offset(m)),
        rays(m, offset) {
    lights = find_lights(mesh, &light_of);
    // The objects with a patch that shares a place with another facing the same way (a rug's, the
    // floor's under it): only their points can be covered (FinalGather::covered).
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      const uint32_t t = mesh.source_triangle[j];
      if (t >= mesh.triangle_object.size() || !rays.overlapped(static_cast<uint32_t>(j))) continue;
      const uint32_t o = mesh.triangle_object[t];
      if (o >= overlapping.size()) overlapping.resize(o + 1, 0);
      overlapping[o] = 1;
    }
    double area = 0.0;
    for (const Light& l : lights) by_area.push_back(area += l.area);
    for (double& v : by_area) v /= area;
  }

  // How a point's emitter sample chooses its light: the cumulative probabilities of the lights
  // in order (the last 1). A pixel's samples share one (Impl::choice); elsewhere (the bounce
  // further, the records) the choice is by area.
  using Choice = const double*;
  double chance(Choice c, std::size_t k) const { return c[k] - (k == 0 ? 0.0 : c[k - 1]); }

  // The choice for the samples of a pixel whose first reflecting hit is x (normal n), into
  // `cdf`: with probability 1 - kByArea a light in proportion to an estimate of what it sends to x
  // unoccluded (its emission's mean x area x cos at x x cos at the light / (r^2 + area), the
  // cosines of its centre, the one at x the largest of its corners'), else by area, so that
  // every light keeps a chance (the sample stays unbiased wherever the estimate is wrong: a
  // light behind a wall). By area where nothing reflects, or past max(kChoiceLights, 2 x spp)
  // lights (the estimate is a pass over them per pixel: an emitting sphere of a thousand
  // triangles would double a pixel's time at low spp).
  static constexpr double kByArea = 0.25;
  static constexpr std::size_t kChoiceLights = 64;
  Choice choice(const glm::dvec3* x, const glm::dvec3& n, std::vector<double>& cdf) const {
    if (!x || lights.size() < 2 || lights.size() > std::max<std::size_t>(kChoiceLights, 2 * static_cast<std::size_t>(options.spp)))
      return by_area.data();
    cdf.resize(lights.size());
    double total = 0.0;
    for (std::size_t k = 0; k < lights.size(); ++k) {
      const Light& l = lights[k];
      glm::dvec3 c(0.0);
      double cos_x = 0.0;
      for (int i = 0; i < l.corners; ++i) {
        const glm::dvec3 d = l.p[static_cast<std::size_t>(i)] - *x;
        const double len = glm::length(d);
        c += l.p[static_cast<std::size_t>(i)] / static_cast<double>(l.corners);
        if (len > 0.0) cos_x = std::max(cos_x, glm::dot(n, d) / len);
      }
      const glm::dvec3 d = *x - c;
      const double r2 = glm::dot(d, d), cos_l = r2 > 0.0 ? glm::dot(l.normal, d) / std::sqrt(r2) : 0.0;
      const double w = (l.emission.x + l.emission.y + l.emission.z) / 3.0 * l.area * cos_x * std::max(cos_l, 0.0) / (r2 + l.area);
      cdf[k] = std::isfinite(w) && w > 0.0 ? w : 0.0;
      total += cdf[k];
    }
    if (!(total > 0.0) || !std::isfinite(total)) return by_area.data();
    double sum = 0.0;
    for (std::size_t k = 0; k < lights.size(); ++k) {
      sum += (1.0 - kByArea) * cdf[k] / total + kByArea * chance(by_area.data(), k);
      cdf[k] = sum;
    }
    for (double& v : cdf) v /= sum;  // the last exactly 1
    return cdf.data();
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

  // The emitter sample's pdf per solid angle, under choice c, of a point of light k at
  // distance^2 `r2` whose direction meets the light's front at cosine `cos_light`.
  double light_pdf(Choice c, std::size_t k, double r2, double cos_light) const { return chance(c, k) * r2 / (cos_light * lights[k].area); }

  // A shadow ray of the direct light and what it brings if nothing blocks it.
  struct ShadowRay {
    glm::dvec3 from, to, light;
  };

  // The emitter sample of the light reflected at point x (its ray leaving at `origin`, normal n)
  // from the unit-square point `light`: a light chosen by c, a point on it by area, and its
  // shadow ray, with the light it brings before rho (with `mis`, weighted against the gather ray
  // that meets an emitter; without, the sample is the whole direct estimate). The first
  // coordinate picks the light and, rescaled within its share, the point's first coordinate
  // on it: stratified points of the square stay stratified over the lights, each stratum a
  // compact cell of a light. False where no ray is cast (no emitter, or one the point does not
  // face or that does not face it).
  bool light_sample(const glm::dvec3& x, const glm::dvec3& origin, const glm::dvec3& n, const std::array<double, 2>& light, bool mis,
                    Choice c, ShadowRay& out, double count = 1.0) const {
    if (lights.empty()) return false;
    const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(std::upper_bound(c, c + lights.size(), light[0]) - c), lights.size() - 1);
    const Light& e = lights[k];
    const double below = k == 0 ? 0.0 : c[k - 1];
    if (!(c[k] > below)) return false;  // no chance (rounding)
    const double s = std::clamp((light[0] - below) / (c[k] - below), 0.0, 1.0);
    const glm::dvec3 y = e.at(s, light[1]);
    const glm::dvec3& ne = e.normal;
    const glm::dvec3 d = y - x;
    const double r2 = glm::dot(d, d);
    if (!(r2 > 0.0)) return false;
    const glm::dvec3 w = d / std::sqrt(r2);
    const double cos_x = glm::dot(n, w), cos_y = -glm::dot(ne, w);
    if (!(cos_x > 0.0 && cos_y > 0.0)) return false;
    const double p_light = count * light_pdf(c, k, r2, cos_y), p_gather = mis ? cos_x / std::numbers::pi : 0.0;
    // E cos_x / pi d(omega) / p_light, with MIS weight p_light / (p_light + p_gather); with
    // `count` emitter samples to one gather ray, each sample's share (Veach's balance heuristic
    // with sample counts: the samples are summed).
    out = {origin, y + ne * offset, e.emission * (cos_x / std::numbers::pi / (p_light + p_gather))};
    return true;
  }

  // The gather ray of the light reflected at a point (its ray leaving at `origin`, normal n),
  // cosine-distributed from the unit-square point `gather`: the reflected light where it lands,
  // into `indirect`, and, if that is an emitter, its light weighted against the emitter sample,
  // into `direct` (both before rho). The solution where it lands, less its emission; where it
  // lands closer than kNear patch sizes (a corner, a contact: where the patch-wise solution is
  // least right), the light reflected there is traced once more instead, from `more`'s points
  // (at `depth` 0 only). Returns where the ray went.
  struct Landed {
    double distance = std::numeric_limits<double>::infinity();  // infinity: it left the scene
    bool emitter = false;                                       // it met an emitter's front
  };
  Landed gathered(const glm::dvec3& origin, const glm::dvec3& n, const std::array<double, 2>& gather, Rng& more, int depth, Choice c,
                  glm::dvec3& direct, glm::dvec3& indirect, uint64_t& cast, double lights = 1.0) const {
    const glm::dvec3 g = cosine_direction(n, gather[0], gather[1]);
    const auto [seen, s] = rays.seen_at(origin, g);
    ++cast;
    if (seen < 0) {
      indirect += glm::dvec3(mesh.background);
      return {};
    }
    const uint32_t k = static_cast<uint32_t>(seen);
    const glm::dvec3 y = origin + g * s;
    const glm::dvec3 e(mesh.emission(k));
    const glm::dvec3 rho_k(mesh.reflectance(k));
    if (depth == 0 && s < kNear * std::sqrt(2.0 * mesh.area[k]) && rho_k != glm::dvec3(0.0)) {
      glm::dvec3 d(0.0), i(0.0);
      const std::array<double, 2> gather_point{more.uniform(), more.uniform()};  // drawn before the light's point
      const std::array<double, 2> light{more.uniform(), more.uniform()};
      reflected(y, glm::dvec3(mesh.normal[k]), {&light, 1}, gather_point, more, 1,
                by_area.data(), d, i, cast);
      indirect += rho_k * (d + i);
    } else {
      indirect += radiosity_at(k, y) - e;
    }
    return {s, emitter_met(k, n, g, s, c, direct, lights)};
  }

  // Whether a gather ray along g from a point of normal n that meets patch k at distance s meets
  // an emitter's front; if so its light, weighted against the emitter sample, into `direct`.
  bool emitter_met(uint32_t k, const glm::dvec3& n, const glm::dvec3& g, double s, Choice c, glm::dvec3& direct,
                   double lights = 1.0) const {
    if (!mesh.emits(k) || light_of[k] < 0) return false;
    const double cos_x = glm::dot(n, g), cos_y = -glm::dot(glm::dvec3(mesh.normal[k]), g);
    if (!(cos_x > 0.0 && cos_y > 0.0)) return false;
    const double p_gather = cos_x / std::numbers::pi, p_light = lights * light_pdf(c, static_cast<std::size_t>(light_of[k]), s * s, cos_y);
    direct += glm::dvec3(mesh.emission(k)) * (p_gather / (p_light + p_gather));
    return true;
  }

  // The gather ray of the direct light alone (a sample that takes the indirect light from the
  // cache, where emitters are large): what it brings if it meets an emitter, into `direct`.
  // `lights`: the emitter samples it is weighed against, as in gathered.
  void emitter_ray(const glm::dvec3& origin, const glm::dvec3& n, const std::array<double, 2>& gather, Choice c, glm::dvec3& direct,
                   uint64_t& cast, double lights = 1.0) const {
    const glm::dvec3 g = cosine_direction(n, gather[0], gather[1]);
    const auto [seen, s] = rays.seen_at(origin, g);
    ++cast;
    if (seen >= 0) emitter_met(static_cast<uint32_t>(seen), n, g, s, c, direct, lights);
  }

  // The light reflected at point x (normal n) toward the viewer, before rho: an emitter sample
  // with its shadow ray from each of the unit-square points `lights` (light_sample, the light
  // chosen by c) and one gather ray (gathered), ray by ray, weighed against each other by the
  // balance heuristic with those counts. Without `indirect_too` the gather ray only looks for
  // an emitter (emitter_ray: the same direct light, to the bit, and nothing into `indirect`).
  void reflected(const glm::dvec3& x, const glm::dvec3& n, std::span<const std::array<double, 2>> lights,
                 const std::array<double, 2>& gather, Rng& more, int depth, Choice c, glm::dvec3& direct, glm::dvec3& indirect,
                 uint64_t& cast, bool indirect_too = true) const {
    const glm::dvec3 origin = x + n * offset;
    const double count = static_cast<double>(lights.size());
    for (const std::array<double, 2>& light : lights) {
      ShadowRay shadow;
      if (light_sample(x, origin, n, light, true, c, shadow, count)) {
        ++cast;
        if (!rays.blocked(shadow.from, shadow.to)) direct += shadow.light;
      }
    }
    if (indirect_too) gathered(origin, n, gather, more, depth, c, direct, indirect, cast, count);
    else emitter_ray(origin, n, gather, c, direct, cast, count);
  }

  // The gather rays of a cache record: 4 per sample of a pixel, within [256, 16384], so that the
  // records' noise stays below the direct light's (bench/RESULTS.md, the irradiance cache).
  int record_rays() const { return std::clamp(4 * options.spp, 256, 16384); }

  // The indirect light arriving at x (normal n) from `rays` stratified gather rays of the record
  // streams of `key` (what a cache record holds, before its mean): the sums of the two
  // interleaved halves of the rays, the least distance one went, how many met an emitter.
  struct Arrival {
    std::array<glm::dvec3, 2> half{glm::dvec3(0.0), glm::dvec3(0.0)};
    double nearest = std::numeric_limits<double>::infinity();
    std::size_t emitters = 0;
  };
  Arrival arrival(const glm::dvec3& x, const glm::dvec3& n, int rays, uint64_t key, uint64_t& cast) const {
    const glm::dvec3 origin = x + n * offset;
    Rng gather(options.seed, key, 0, kRecordGather), more(options.seed, key, 0, kRecordMore);
    thread_local std::vector<std::array<double, 2>> gathers;
    stratified_square(rays, gather, gathers);
    Arrival a;
    for (std::size_t i = 0; i < gathers.size(); ++i) {
      glm::dvec3 direct(0.0);
      const Landed l = gathered(origin, n, gathers[i], more, 0, by_area.data(), direct, a.half[i % 2], cast);
      a.nearest = std::min(a.nearest, l.distance);
      a.emitters += l.emitter;
    }
    return a;
  }

  // The cache record of raster point (gx, gy) of the view `frame`, `key` its key in the store.
  CacheRecord make_record(const CameraFrame& frame, int gx, int gy, uint64_t key, uint64_t& cast) const {
    CacheRecord r;
    const glm::dvec3 dir = frame.direction(gx, gy);
    const auto [hit, t] = rays.seen_at(frame.eye, dir);
    ++cast;
    if (hit < 0 || mesh.reflectance(static_cast<uint32_t>(hit)) == glm::vec3(0.0f)) return r;
    r.x = frame.eye + dir * t;
    r.n = glm::dvec3(mesh.normal[static_cast<std::size_t>(hit)]);
    const int rays = record_rays();
    const Arrival a = arrival(r.x, r.n, rays, key, cast);
    r.e = (a.half[0] + a.half[1]) / static_cast<double>(rays);
    r.r = a.nearest;
    r.emitters = static_cast<double>(a.emitters) / static_cast<double>(rays);
    r.valid = true;
    return r;
  }

  // A block of the cache's grid: raster [x0, x0 + side] x [y0, y0 + side] and its corner
  // records (x0, y0), (x0 + side, y0), (x0, y0 + side), (x0 + side, y0 + side); `fits` whether
  // they make a block (else it is a pixel on an edge, whose samples take the corners on their own
  // surface below kEdgeSpp). No corners: no cache. `mis`: a corner's rays met emitters more than kCacheMis of
  // the time, so the block's samples weigh their emitter samples against a gather ray of their
  // own (MIS: light sampling alone is noisy near a large emitter or among many).
  struct Block {
    int x0 = 0, y0 = 0, side = 1;
    std::array<const CacheRecord*, 4> c{};
    bool fits = false, mis = false;
  };

  // Whether points x1 (normal n1) and x2 (normal n2) are of one surface: they face ways at most
  // acos(kCacheCos) apart, and each lies in the other's plane to kCachePlane of their distance.
  static bool one_surface(const glm::dvec3& x1, const glm::dvec3& n1, const glm::dvec3& x2, const glm::dvec3& n2) {
    if (glm::dot(n1, n2) < kCacheCos) return false;
    const glm::dvec3 d = x2 - x1;
    const double len = glm::length(d);
    return std::abs(glm::dot(n1, d)) <= kCachePlane * len && std::abs(glm::dot(n2, d)) <= kCachePlane * len;
  }

  // Whether the indirect light at corner records c differs by more than kCacheContrast times.
  static bool steep(const std::array<const CacheRecord*, 4>& c) {
    double dim = std::numeric_limits<double>::infinity(), bright = 0.0;
    for (const CacheRecord* a : c) {
      const double y = a->e.x + a->e.y + a->e.z;
      dim = std::min(dim, y);
      bright = std::max(bright, y);
    }
    return bright > kCacheContrast * dim;
  }

  // Whether corner records c make a block of `side` pixels the indirect light can be
  // interpolated over (the criteria at kCacheSpacing; r is each record's least distance).
  static bool fits(const std::array<const CacheRecord*, 4>& c, int side) {
    double r = std::numeric_limits<double>::infinity(), extent = 0.0;
    for (const CacheRecord* a : c) {
      if (!a->valid) return false;
      r = std::min(r, a->r);
    }
    if (steep(c)) return false;
    for (std::size_t a = 0; a < 4; ++a)
      for (std::size_t b = a + 1; b < 4; ++b) {
        if (!one_surface(c[a]->x, c[a]->n, c[b]->x, c[b]->n)) return false;
        extent = std::max(extent, glm::length(c[b]->x - c[a]->x));
      }
    return side <= kCacheAny || extent <= kCacheWard * r;
  }

  // Whether each two corners of c that are of one surface see each other (nothing between them
  // just above it): a thin wall standing on a floor between two corners on that floor, which
  // blocks of kCacheAny pixels or fewer (taken at any distance) and edges' blocks would
  // otherwise interpolate across.
  bool in_sight(const std::array<const CacheRecord*, 4>& c, uint64_t& cast) const {
    for (std::size_t a = 0; a < 4; ++a)
      for (std::size_t b = a + 1; b < 4; ++b)
        if (c[a]->valid && c[b]->valid && one_surface(c[a]->x, c[a]->n, c[b]->x, c[b]->n)) {
          ++cast;
          if (rays.blocked(c[a]->x + c[a]->n * offset, c[b]->x + c[b]->n * offset)) return false;
        }
    return true;
  }

  // The block of pixel (px, py): the largest that fits, from kCacheSpacing pixels down to
  // kCacheLeast (which is taken if it does not, an edge, below kEdgeSpp; from kEdgeSpp on an edge
  // gives no cache). A block of kCacheAny pixels or fewer whose corners of one surface do not all
  // see each other is split, and at kCacheLeast gives no cache (its samples gather for
  // themselves).
  Block block(const CameraFrame& frame, RecordStore& store, int px, int py, uint64_t& cast) const {
    const uint64_t row = static_cast<uint64_t>(options.width) + kCacheSpacing + 1;
    for (int side = kCacheSpacing;; side /= 2) {
      Block b{px / side * side, py / side * side, side, {}, false};
      for (int k = 0; k < 4; ++k) {
        const int gx = b.x0 + (k & 1) * side, gy = b.y0 + (k >> 1) * side;
        const uint64_t key = static_cast<uint64_t>(gy) * row + static_cast<uint64_t>(gx);
        b.c[static_cast<std::size_t>(k)] = &store.get(key, [&] { return make_record(frame, gx, gy, key, cast); });
      }
      b.fits = fits(b.c, side);
      if (side <= kCacheAny && (b.fits || side <= kCacheLeast) && !in_sight(b.c, cast)) {
        if (side > kCacheLeast) continue;
        return Block{};
      }
      if (!b.fits && side <= kCacheLeast && options.spp >= kEdgeSpp) return Block{};
      if (b.fits || side <= kCacheLeast) {
        for (const CacheRecord* r : b.c) b.mis = b.mis || r->emitters > kCacheMis;
        return b;
      }
    }
  }

  // The cached indirect light (before rho) at point x (normal n) that the sample at raster (sx,
  // sy) sees, interpolated over block b's corners (bilinear in raster space) into `out`. A corner
  // is of x's surface if it faces x's way and x lies in its plane (both by the criteria at
  // kCacheSpacing); in a block that fits, every corner must be, else only those that are count
  // (an edge's pixel). False where none can be taken: the sample gathers for itself.
  bool cached(const Block& b, const glm::dvec3& x, const glm::dvec3& n, double sx, double sy, glm::dvec3& out) const {
    if (!b.c[0]) return false;
    const double u = std::clamp((sx - b.x0) / b.side, 0.0, 1.0), v = std::clamp((sy - b.y0) / b.side, 0.0, 1.0);
    const std::array<double, 4> w{(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v};
    glm::dvec3 sum(0.0);
    double weight = 0.0;
    for (std::size_t k = 0; k < 4; ++k) {
      const CacheRecord& r = *b.c[k];
      const bool here = r.valid && one_surface(x, n, r.x, r.n);
      if (!here && b.fits) return false;
      if (here) sum += w[k] * r.e, weight += w[k];
    }
    if (!(weight > 0.0)) return false;
    out = sum / weight;
    return true;
  }

  // Pixel (px, py) of the view `frame` into `out` at (ox, oy); returns the rays it cast. The
  // samples go in batches: the batch's primary rays (one origin, nearly one direction) traced
  // together as a stream, then their shadow rays (towards the same emitters) as another, then
  // each sample's gather ray (every way: one by one, a stream gains nothing) unless it takes the
  // indirect light from the cache (`store`; null: none), whose records' rays count into
  // `record_cast`; each sample's light is added in sample order, as one sample at a time would.
  uint64_t pixel(const CameraFrame& frame, RecordStore* store, int px, int py, int ox, int oy, GatherPasses& out,
                 uint64_t& record_cast) const {
    const uint64_t index = static_cast<uint64_t>(py) * static_cast<uint64_t>(options.width) + static_cast<uint64_t>(px);
    // Each of the sample's three 2D choices (the position in the pixel, the emitter point, the
    // gather direction) stratified over the pixel's samples, the sets paired in random order
    // (in buffers of this thread's, kept from pixel to pixel).
    Rng jitter(options.seed, index, 0, kJitter), light(options.seed, index, 0, kLight), gather(options.seed, index, 0, kGather),
        more(options.seed, index, 0, kMore);
    thread_local std::vector<std::array<double, 2>> positions, emitter_points, gathers;
    thread_local std::vector<double> cdf;
    Choice pick = nullptr;  // the emitter samples' choice of lights: set at the first reflecting hit
    stratified_square(options.spp, jitter, positions);
    stratified_square(options.spp, light, emitter_points);
    stratified_square(options.spp, gather, gathers);
    const Block cache = store ? block(frame, *store, px, py, record_cast) : Block{};
    // Gather rays of a sample that takes nothing from the cache (one without a cache).
    const int own_rays = store && options.spp >= kEdgeSpp ? kEdgeRays : 1;
    constexpr std::size_t kBatch = 64;
    struct Sample {
      glm::dvec3 seen;  // what the camera sees emitted (or the background)
      glm::dvec3 rho;   // 0: nothing reflected
      glm::dvec3 origin, normal;
      int shadow;       // index into the batch's shadow rays, or -1
      bool cached;      // the indirect light is `indirect`, from the cache
      glm::dvec3 indirect;
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
        a.cached = cached(cache, x, a.normal, px + positions[b0 + i][0], py + positions[b0 + i][1], a.indirect);
        ShadowRay r;
        if (!pick) pick = choice(&x, a.normal, cdf);
        if (light_sample(x, a.origin, a.normal, emitter_points[b0 + i], !a.cached || cache.mis, pick, r)) {
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
        if (a.cached) {
          r = a.indirect;
          if (cache.mis) emitter_ray(a.origin, a.normal, gathers[b0 + i], pick, d, cast);
        } else if (own_rays == 1) {
          gathered(a.origin, a.normal, gathers[b0 + i], more, 0, pick, d, r, cast);
        } else {
          // The first ray from the pixel's strata, the others from `more`; each weighed against
          // the emitter sample as if alone (the balance heuristic's weights for one ray of each
          // sum to one per direction, so their mean stays unbiased).
          glm::dvec3 dk(0.0), rk(0.0);
          gathered(a.origin, a.normal, gathers[b0 + i], more, 0, pick, dk, rk, cast);
          for (int k = 1; k < own_rays; ++k) gathered(a.origin, a.normal, {more.uniform(), more.uniform()}, more, 0, pick, dk, rk, cast);
          d += dk / static_cast<double>(own_rays);
          r += rk / static_cast<double>(own_rays);
        }
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
  if (int64_t{options.width} * options.height > kMaxImagePixels)
    fail("final gather: image {}x{}: more than {} pixels", options.width, options.height, kMaxImagePixels);
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
  return static_cast<int>(worker_threads(threads));
}

void FinalGather::leaving(const std::vector<SurfacePoint>& points, uint64_t key, glm::dvec3& direct, glm::dvec3& indirect,
                          uint64_t& cast, int lights, bool indirect_too) const {
  direct = indirect = glm::dvec3(0.0);
  if (points.empty()) return;
  if (lights < 1 || lights > 64) fail("leaving: {} emitter samples a point (1..64)", lights);
  const Impl& m = *impl_;
  const int n = static_cast<int>(points.size());
  Rng light(m.options.seed, key, 1, kLight), gather(m.options.seed, key, 1, kGather), more(m.options.seed, key, 1, kMore);
  std::vector<std::array<double, 2>> emitter_points, gathers;
  std::vector<double> cdf;
  stratified_square(n * lights, light, emitter_points);
  stratified_square(n, gather, gathers);
  const Impl::Choice pick = m.choice(&points[0].x, points[0].normal, cdf);
  for (int i = 0; i < n; ++i) {
    const SurfacePoint& p = points[static_cast<std::size_t>(i)];
    direct += p.emission;
    if (p.rho == glm::dvec3(0.0)) continue;
    glm::dvec3 d(0.0), r(0.0);
    m.reflected(p.x, p.normal, std::span(emitter_points).subspan(static_cast<std::size_t>(i * lights), static_cast<std::size_t>(lights)),
                gathers[static_cast<std::size_t>(i)], more, 0, pick, d, r, cast, indirect_too);
    direct += p.rho * d;
    indirect += p.rho * r;
  }
  direct /= static_cast<double>(n);
  indirect /= static_cast<double>(n);
}

glm::dvec3 FinalGather::arriving(const glm::dvec3& x, const glm::dvec3& n, int rays, uint64_t key, glm::dvec3& error, double& nearest,
                                 uint64_t& cast) const {
  if (rays < 2 || rays > 65536) fail("final gather: {} rays a point (2..65536)", rays);
  const Impl::Arrival a = impl_->arrival(x, n, rays, key, cast);
  nearest = a.nearest;
  const double na = static_cast<double>((rays + 1) / 2), nb = static_cast<double>(rays / 2);
  error = glm::abs(a.half[0] / na - a.half[1] / nb) * std::sqrt(na * nb) / (na + nb);
  return (a.half[0] + a.half[1]) / (na + nb);
}

bool FinalGather::in_sight(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& n) const {
  const Impl& m = *impl_;
  return !m.rays.blocked(a + n * m.offset, b + n * m.offset);
}

bool FinalGather::enclosed(const glm::dvec3& x, const glm::dvec3& n) const {
  const Impl& m = *impl_;
  const glm::dvec3 origin = x + n * m.offset;
  const auto from_behind = [&](const glm::dvec3& d) {
    const int64_t k = m.rays.nearest(origin, d);
    return k >= 0 && glm::dot(glm::dvec3(m.mesh.normal[static_cast<std::size_t>(k)]), d) > 0.0;
  };
  if (!from_behind(n)) return false;
  const glm::dvec3 helper = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 u = glm::normalize(glm::cross(helper, n)), v = glm::cross(n, u);
  const double c = 0.5, s = std::sqrt(0.75);  // 60 degrees from n
  for (const glm::dvec3& side : {u, -u, v, -v})
    if (!from_behind(n * c + side * s)) return false;
  return true;
}

bool FinalGather::covered(const glm::dvec3& x, const glm::dvec3& n, uint32_t object) const {
  const Impl& m = *impl_;
  if (object >= m.overlapping.size() || !m.overlapping[object]) return false;
  const int64_t top = m.rays.on_top(x, n);
  if (top < 0) return false;
  const uint32_t t = m.mesh.source_triangle[static_cast<std::size_t>(top)];
  return t < m.mesh.triangle_object.size() && m.mesh.triangle_object[t] != object;
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
  check_camera_reach(camera, impl_->mesh.bound_center, impl_->mesh.bound_radius, "final gather");
  const CameraFrame frame = camera_frame(camera, o.width, o.height, "final gather");
  GatherPasses out = GatherPasses::of_size(x1 - x0, y1 - y0);
  // The work: the region's parts in tiles of the cache's grid (kCacheSpacing pixels a side),
  // those of one colour of a checkerboard first. Tiles worked on at once then share at most a
  // corner record, and a tile of the other colour finds its edges' records made: threads taking
  // rows in turn waited for the records the other was making (a fifth of the time at 36 spp).
  std::vector<std::array<int, 4>> tiles;
  for (int colour = 0; colour < 2; ++colour)
    for (int ty = y0 / kCacheSpacing; ty * kCacheSpacing < y1; ++ty)
      for (int tx = x0 / kCacheSpacing; tx * kCacheSpacing < x1; ++tx)
        if (((tx + ty) & 1) == colour)
          tiles.push_back({std::max(x0, tx * kCacheSpacing), std::max(y0, ty * kCacheSpacing), std::min(x1, (tx + 1) * kCacheSpacing),
                           std::min(y1, (ty + 1) * kCacheSpacing)});
  const unsigned threads = static_cast<unsigned>(o.thread_count());
  const std::shared_ptr<RecordStore> records = impl_->records(camera);
  std::vector<uint64_t> cast(threads, 0), record_cast(threads, 0);
  // Whole tiles each: no pixel is written by two threads.
  parallel_for(tiles.size(), 1, threads, [&](std::size_t k, std::size_t, unsigned t) {
    const auto [tx0, ty0, tx1, ty1] = tiles[k];
    for (int y = ty0; y < ty1; ++y) {
      for (int x = tx0; x < tx1; ++x) cast[t] += impl_->pixel(frame, records.get(), x, y, x - x0, y - y0, out, record_cast[t]);
      if (t == 0 && between) between();
    }
  });
  for (uint64_t c : cast) out.rays += c;
  for (uint64_t c : record_cast) out.record_rays += c;
  return out;
}

GatherPasses FinalGather::render(const Camera& camera) const {
  return render(camera, 0, 0, impl_->options.width, impl_->options.height);
}

}  // namespace sirad
