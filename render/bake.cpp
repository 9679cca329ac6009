// sirad: a lightmap baked from a radiosity solution (see bake.h).
#include "render/bake.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <unordered_map>

#include <glm/geometric.hpp>

#include "scene/rays.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/polygon.h"

namespace sirad {

namespace {

// The streams of a texel's sample positions (the gather's own use 1..6 of the last key).
constexpr uint64_t kTexelJitter = 7;

// A chart's triangle in texel coordinates, with its corners in the scene.
struct Flat {
  std::array<glm::dvec2, 3> q;
  std::array<glm::dvec3, 3> p;
  glm::dvec3 normal, rho, emission;
  uint32_t object = 0;
};

// A chart's flat triangles by texel: those whose bounds reach each texel of its rectangle, so
// that a point finds its triangle among a few (a UV island of a curved surface has thousands).
class FlatIndex {
 public:
  FlatIndex(const Chart& chart, const std::vector<Flat>& flat) : chart_(chart), flat_(flat), start_(cells() + 1, 0) {
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<uint32_t> at(start_.begin(), start_.end() - 1);
      for (std::size_t f = 0; f < flat.size(); ++f) {
        const auto& q = flat[f].q;
        const int x0 = clamp_x(std::min({q[0].x, q[1].x, q[2].x})), x1 = clamp_x(std::max({q[0].x, q[1].x, q[2].x}));
        const int y0 = clamp_y(std::min({q[0].y, q[1].y, q[2].y})), y1 = clamp_y(std::max({q[0].y, q[1].y, q[2].y}));
        for (int y = y0; y <= y1; ++y)
          for (int x = x0; x <= x1; ++x) {
            const std::size_t cell = static_cast<std::size_t>(y) * static_cast<std::size_t>(chart.width) + static_cast<std::size_t>(x);
            if (pass == 0) ++start_[cell + 1];
            else items_[at[cell]++] = static_cast<uint32_t>(f);
          }
      }
      if (pass == 0) {
        for (std::size_t k = 1; k < start_.size(); ++k) start_[k] += start_[k - 1];
        items_.resize(start_.back());
      }
    }
  }

  // The first triangle (in the chart's order) that holds texel point `at`, with its barycentric
  // coordinates; nullptr where none does.
  const Flat* find(const glm::dvec2& at, glm::dvec3& w) const {
    if (chart_.width <= 0 || chart_.height <= 0) return nullptr;
    const std::size_t cell = static_cast<std::size_t>(clamp_y(at.y)) * static_cast<std::size_t>(chart_.width) + static_cast<std::size_t>(clamp_x(at.x));
    for (uint32_t k = start_[cell]; k < start_[cell + 1]; ++k)
      if (in_triangle(flat_[items_[k]].q, at, w)) return &flat_[items_[k]];
    return nullptr;
  }

 private:
  std::size_t cells() const { return static_cast<std::size_t>(std::max(chart_.width, 0)) * static_cast<std::size_t>(std::max(chart_.height, 0)); }
  int clamp_x(double x) const { return std::clamp(static_cast<int>(std::floor(x)) - chart_.x, 0, std::max(chart_.width - 1, 0)); }
  int clamp_y(double y) const { return std::clamp(static_cast<int>(std::floor(y)) - chart_.y, 0, std::max(chart_.height - 1, 0)); }

  const Chart& chart_;
  const std::vector<Flat>& flat_;
  std::vector<uint32_t> start_, items_;
};

// Fills chart c's texels in its rectangle [x0, x1) x [y0, y1) that have no value (coverage 0)
// with the mean of their neighbours (8-connected) of the chart that have one, ring by ring, each
// ring from the values before it. Texels of other charts are neither read nor written.
void dilate(Lightmap& m, const std::vector<uint32_t>& owner, uint32_t c, int x0, int y0, int x1, int y1) {
  const int w = m.combined.width;
  std::vector<uint8_t> has(static_cast<std::size_t>((x1 - x0) * (y1 - y0)));
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * w + x;
      // Another chart's texel counts as one with a value: it is never filled from this one's.
      has[static_cast<std::size_t>((y - y0) * (x1 - x0) + (x - x0))] = owner[k] != c || m.coverage[k] > 0;
    }
  const auto mine = [&](int a, int b) { return owner[static_cast<std::size_t>(b) * w + a] == c; };
  for (int ring = 0; ring < (x1 - x0) + (y1 - y0); ++ring) {
    std::vector<std::array<int, 2>> filled;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        if (has[static_cast<std::size_t>((y - y0) * (x1 - x0) + (x - x0))]) continue;
        glm::vec3 d(0.0f), i(0.0f), e(0.0f);
        int n = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int a = x + dx, b = y + dy;
            if (a < x0 || a >= x1 || b < y0 || b >= y1 || !mine(a, b) || !has[static_cast<std::size_t>((b - y0) * (x1 - x0) + (a - x0))]) continue;
            d += m.direct.at(a, b), i += m.indirect.at(a, b), e += m.error.at(a, b), ++n;
          }
        if (n == 0) continue;
        m.direct.at(x, y) = d / float(n), m.indirect.at(x, y) = i / float(n), m.error.at(x, y) = e / float(n);
        m.combined.at(x, y) = m.direct.at(x, y) + m.indirect.at(x, y);
        filled.push_back({x, y});
      }
    if (filled.empty()) return;
    for (const auto& [x, y] : filled) has[static_cast<std::size_t>((y - y0) * (x1 - x0) + (x - x0))] = 1;
  }
}

// The cache of a chart's indirect light: records at texel corners kCacheSides[0] (or, where
// those do not make a block, kCacheSides[1]) texels apart, each kRecordRays gather rays
// (FinalGather::arriving). A texel takes the bilinear blend of its block's four corners where
// all four lie on the chart and outside any solid, see each other, differ by at most
// kCacheContrast times (the sum of the channels, each record taken two of its standard errors
// towards the others: noise alone does not make a block steep) and, for the larger blocks, lie within
// kCacheWard of the least distance their rays went (the gather's criteria, render/gather.cpp;
// the smaller blocks are taken at any distance, as the image's of kCacheAny pixels are: near a
// wall Ward's criterion would refuse a light that changes there nearly linearly); else its
// samples gather for themselves. 256 rays a record over 4 x 4 texels cost a texel 16 rays, as 16
// samples' own gather rays do, and leave smooth light where those leave speckles.
constexpr std::array<int, 2> kCacheSides = {4, 2};
constexpr int kRecordRays = 256;
constexpr double kCacheContrast = 1.25, kCacheWard = 0.25;

struct Record {
  bool valid = false;
  glm::dvec3 x{0.0}, normal{0.0}, e{0.0}, se{0.0};
  double r = 0.0;
};

// A block's corners lie in one plane within this (a curved chart of the file's layout is
// interpolated only where it is flat within 2 degrees, as sirad's charts are).
const double kCacheFlat = std::cos(2.0 * std::numbers::pi / 180.0);

class ChartCache {
 public:
  ChartCache(const Chart& chart, const FlatIndex& flat, const FinalGather& gather, uint64_t base, int width)
      : chart_(chart), flat_(flat), gather_(gather), base_(base), width_(width), texel_(chart.texel) {}

  // The arriving indirect light (before the reflectance) at texel point (sx, sy) of texel (x, y),
  // and its standard error's estimate; false where the texel's block is not usable.
  bool at(int x, int y, double sx, double sy, glm::dvec3& e, glm::dvec3& se, uint64_t& cast) {
    for (int side : kCacheSides) {
      const int bx = chart_.x + (x - chart_.x) / side * side, by = chart_.y + (y - chart_.y) / side * side;
      std::array<const Record*, 4> c{};
      for (int k = 0; k < 4; ++k) c[static_cast<std::size_t>(k)] = &record(bx + (k & 1) * side, by + (k >> 1) * side, cast);
      if (!usable(c, (static_cast<uint64_t>(by) * (static_cast<uint64_t>(width_) + 1) + static_cast<uint64_t>(bx)) * 8 + side, side, cast))
        continue;
      const double u = std::clamp((sx - bx) / side, 0.0, 1.0), v = std::clamp((sy - by) / side, 0.0, 1.0);
      const std::array<double, 4> w = {(1 - u) * (1 - v), u * (1 - v), (1 - u) * v, u * v};
      e = se = glm::dvec3(0.0);
      for (std::size_t k = 0; k < 4; ++k) e += w[k] * c[k]->e, se += w[k] * w[k] * c[k]->se * c[k]->se;
      se = glm::sqrt(se);
      return true;
    }
    return false;
  }

 private:
  const Record& record(int gx, int gy, uint64_t& cast) {
    const uint64_t key = static_cast<uint64_t>(gy) * (static_cast<uint64_t>(width_) + 1) + static_cast<uint64_t>(gx);
    auto [it, added] = records_.try_emplace(key);
    if (!added) return it->second;
    Record& r = it->second;
    const glm::dvec2 at(gx, gy);
    glm::dvec3 w;
    const Flat* f = flat_.find(at, w);
    if (!f) return r;
    r.x = f->p[0] * w.x + f->p[1] * w.y + f->p[2] * w.z;
    r.normal = chart_.flat ? chart_.normal : f->normal;
    if (gather_.enclosed(r.x, r.normal) || gather_.covered(r.x, r.normal, f->object)) return r;
    r.e = gather_.arriving(r.x, r.normal, kRecordRays, base_ + key, r.se, r.r, cast);
    r.valid = true;
    return r;
  }

  // Whether the block of corners c (`key` its own) may be interpolated over.
  bool usable(const std::array<const Record*, 4>& c, uint64_t key, int side, uint64_t& cast) {
    if (auto it = blocks_.find(key); it != blocks_.end()) return it->second;
    bool ok = true;
    // The contrast of what the records' light could be: each taken 2 standard errors towards
    // the others (a record's noise alone does not make a block steep).
    double dim = INFINITY, bright = 0, r = INFINITY;
    for (const Record* a : c) {
      ok = ok && a->valid;
      if (!ok) break;
      const double y = a->e.x + a->e.y + a->e.z, se = a->se.x + a->se.y + a->se.z;
      dim = std::min(dim, y + 2 * se), bright = std::max(bright, y - 2 * se), r = std::min(r, a->r);
      ok = glm::dot(a->normal, c[0]->normal) >= kCacheFlat;
    }
    ok = ok && bright <= kCacheContrast * dim && (side <= kCacheSides.back() || side * texel_ * std::sqrt(2.0) <= kCacheWard * r);
    for (std::size_t a = 0; a < 4 && ok; ++a)
      for (std::size_t b = a + 1; b < 4 && ok; ++b) {
        ++cast;
        ok = gather_.in_sight(c[a]->x, c[b]->x, c[a]->normal);
      }
    blocks_.emplace(key, ok);
    return ok;
  }

  const Chart& chart_;
  const FlatIndex& flat_;
  const FinalGather& gather_;
  uint64_t base_;
  int width_;
  double texel_;
  std::unordered_map<uint64_t, Record> records_;
  std::unordered_map<uint64_t, bool> blocks_;
};

// Seams (Atlas::seams) are matched by projections (Kaczmarz): at points kSeamPoints texels apart
// along each, the bilinear lookups of its two sides are both moved to their mean, each by
// changing its four texels in proportion to their weights; kSeamPasses passes over all seams in
// order (on a floor's diagonal seam 16 passes left 1.1 % between the sides, 64 leave 0.02 %;
// points half a texel apart left 0.6 %, the grids being turned to each other). A texel changes
// only within a lookup's reach of a seam (1.5 texels). At most kMaxSeamPoints points in all
// (about 150 MB; a seam's points past that, in the atlas's order, are not matched).
constexpr double kSeamPoints = 0.25;
constexpr int kSeamPasses = 64;
constexpr std::size_t kMaxSeamPoints = std::size_t{1} << 21;

// One side of a seam point: the four texels of its bilinear lookup and their weights.
struct Footprint {
  std::array<uint32_t, 4> texel{};
  std::array<float, 4> w{};
  bool ok = false;
};

// A side whose lookup has less than this weight on texels with samples of their own (the rest
// dilated: a face under a solid, beyond its outline) says nothing of the light there: the
// point is not matched, so no light is pulled from the other side into a hidden face.
constexpr double kSeamSampled = 0.25;

Footprint footprint(const Atlas& atlas, const std::vector<float>& coverage, uint32_t chart, const glm::dvec2& at) {
  Footprint f;
  const double x = at.x - 0.5, y = at.y - 0.5;
  const int i = static_cast<int>(std::floor(x)), j = static_cast<int>(std::floor(y));
  const double fx = x - i, fy = y - j;
  if (i < 0 || j < 0 || i + 1 >= atlas.width || j + 1 >= atlas.height) return f;
  for (std::size_t k = 0; k < 4; ++k) {
    const std::size_t t = static_cast<std::size_t>(j + static_cast<int>(k >> 1)) * static_cast<std::size_t>(atlas.width) +
                          static_cast<std::size_t>(i + static_cast<int>(k & 1));
    f.texel[k] = static_cast<uint32_t>(t);
    f.w[k] = static_cast<float>(((k & 1) ? fx : 1 - fx) * ((k >> 1) ? fy : 1 - fy));
    if (f.w[k] > 0 && atlas.owner[t] != chart) return f;  // another chart's texel: no lookup here
  }
  double sampled = 0;
  for (std::size_t k = 0; k < 4; ++k) sampled += coverage[f.texel[k]] > 0 ? f.w[k] : 0.0;
  f.ok = sampled >= kSeamSampled;
  return f;
}

void match_seams(Lightmap& m, const Atlas& atlas) {
  if (atlas.seams.empty()) return;
  const glm::dvec2 size(atlas.width, atlas.height);
  std::vector<std::array<Footprint, 2>> points;
  for (const Seam& seam : atlas.seams) {
    const glm::dvec2 a0 = glm::dvec2(seam.uv_a[0]) * size, a1 = glm::dvec2(seam.uv_a[1]) * size;
    const glm::dvec2 b0 = glm::dvec2(seam.uv_b[0]) * size, b1 = glm::dvec2(seam.uv_b[1]) * size;
    const double length = std::max(glm::length(a1 - a0), glm::length(b1 - b0));
    const int n = std::clamp(static_cast<int>(std::ceil(length / kSeamPoints)), 1, 1 << 16);
    for (int s = 0; s < n && points.size() < kMaxSeamPoints; ++s) {
      const double t = (s + 0.5) / n;
      std::array<Footprint, 2> p = {footprint(atlas, m.coverage, atlas.chart_of[seam.a], a0 + t * (a1 - a0)),
                                    footprint(atlas, m.coverage, atlas.chart_of[seam.b], b0 + t * (b1 - b0))};
      if (p[0].ok && p[1].ok) points.push_back(p);
    }
  }
  std::vector<glm::vec3> before = m.combined.pixels;
  auto& v = m.combined.pixels;
  for (int pass = 0; pass < kSeamPasses; ++pass)
    for (const auto& p : points) {
      std::array<glm::dvec3, 2> look{};
      std::array<double, 2> norm{};
      for (std::size_t side = 0; side < 2; ++side)
        for (std::size_t k = 0; k < 4; ++k) {
          const double w = p[side].w[k];
          look[side] += w * glm::dvec3(v[p[side].texel[k]]), norm[side] += w * w;
        }
      const glm::dvec3 mean = 0.5 * (look[0] + look[1]);
      for (std::size_t side = 0; side < 2; ++side)
        for (std::size_t k = 0; k < 4; ++k)
          v[p[side].texel[k]] += glm::vec3(double(p[side].w[k]) * (mean - look[side]) / norm[side]);
    }
  // The layers follow the sum: direct and indirect scaled by the texel's change (the change in
  // the indirect light where the texel had none).
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (v[k] == before[k]) continue;
    v[k] = glm::max(v[k], glm::vec3(0.0f));
    for (int c = 0; c < 3; ++c) {
      if (before[k][c] > 0) {
        const float r = v[k][c] / before[k][c];
        m.direct.pixels[k][c] *= r, m.indirect.pixels[k][c] *= r;
      } else {
        m.indirect.pixels[k][c] = v[k][c] - m.direct.pixels[k][c];
      }
    }
  }
}

}  // namespace

Lightmap bake_lightmap(const Scene& scene, const Atlas& atlas, const FinalGather& gather, int samples, int lights, bool seams) {
  if (samples < 1 || samples > 4096) fail("lightmap: {} samples per texel (1..4096)", samples);
  if (lights < 1 || lights > 64) fail("lightmap: {} emitter samples per sample (1..64)", lights);
  if (atlas.uv.size() != scene.triangles.size() || atlas.width < 1 || atlas.height < 1 ||
      atlas.owner.size() != static_cast<std::size_t>(atlas.width) * static_cast<std::size_t>(atlas.height))
    fail("lightmap: an atlas of {} triangles for a scene of {}", atlas.uv.size(), scene.triangles.size());
  const int W = atlas.width, H = atlas.height;
  Lightmap m;
  for (Image* image : {&m.direct, &m.indirect, &m.combined, &m.error}) {
    image->width = W, image->height = H;
    image->pixels.assign(static_cast<std::size_t>(W) * H, glm::vec3(0.0f));
  }
  m.coverage.assign(static_cast<std::size_t>(W) * H, 0.0f);
  std::vector<uint64_t> cast(atlas.charts.size(), 0), cached_texels(atlas.charts.size(), 0);
  const uint64_t seed = gather.options().seed;
  const uint64_t texels = static_cast<uint64_t>(W) * static_cast<uint64_t>(H);
  parallel_for(atlas.charts.size(), 1, static_cast<unsigned>(gather.options().thread_count()), [&](std::size_t c, std::size_t, unsigned) {
    // Step 1: the chart's triangles flat, in texel coordinates.
    const Chart& chart = atlas.charts[c];
    std::vector<Flat> flat;
    for (uint32_t t : chart.triangles) {
      const Triangle& tri = scene.triangles[t];
      Flat f;
      for (std::size_t k = 0; k < 3; ++k) {
        f.q[k] = {double(atlas.uv[t][k].x) * W, double(atlas.uv[t][k].y) * H};
        f.p[k] = glm::dvec3(tri.p[k]);
      }
      const glm::dvec3 n = glm::cross(f.p[1] - f.p[0], f.p[2] - f.p[0]);
      if (!(glm::length(n) > 0.0)) continue;
      f.normal = glm::normalize(n);
      f.rho = glm::dvec3(scene.materials.at(tri.material).reflectance);
      f.emission = glm::dvec3(scene.materials.at(tri.material).emission);
      f.object = tri.object;
      flat.push_back(f);
    }
    // Step 2: each texel's samples on the chart's faces, the light leaving them.
    std::vector<std::array<double, 2>> positions;
    std::vector<FinalGather::SurfacePoint> points;
    std::array<std::vector<FinalGather::SurfacePoint>, 2> halves;
    std::vector<std::array<double, 2>> kept;  // the kept samples' texel points
    const FlatIndex index(chart, flat);
    ChartCache cache(chart, index, gather, 2 * texels, W);
    for (int y = chart.y; y < chart.y + chart.height; ++y)
      for (int x = chart.x; x < chart.x + chart.width; ++x) {
        const uint64_t key = static_cast<uint64_t>(y) * static_cast<uint64_t>(W) + static_cast<uint64_t>(x);
        if (atlas.owner[static_cast<std::size_t>(key)] != c) continue;  // another chart's (the file's layout)
        Rng jitter(seed, key, 1, kTexelJitter);
        stratified_square(samples, jitter, positions);
        points.clear(), kept.clear();
        for (const auto& [sx, sy] : positions) {
          const glm::dvec2 at(x + sx, y + sy);
          glm::dvec3 w;
          const Flat* f = index.find(at, w);
          if (!f) continue;  // beyond the chart's outline
          const glm::dvec3 p = f->p[0] * w.x + f->p[1] * w.y + f->p[2] * w.z;
          if (gather.enclosed(p, f->normal)) continue;             // inside a solid
          if (gather.covered(p, f->normal, f->object)) continue;   // under a rug laid on it
          points.push_back({p, f->normal, f->rho, f->emission});
          kept.push_back({at.x, at.y});
        }
        if (points.empty()) continue;
        // The indirect light from the chart's cache where the texel's block is usable.
        glm::dvec3 cached(0.0), cached_se(0.0);
        bool from_cache = true;
        for (std::size_t s = 0; s < points.size() && from_cache; ++s) {
          glm::dvec3 e(0.0), se(0.0);  // as they are where the cache has no block
          from_cache = cache.at(x, y, kept[s][0], kept[s][1], e, se, cast[c]);
          cached += points[s].rho * e, cached_se += points[s].rho * se;
        }
        cached /= static_cast<double>(points.size()), cached_se /= static_cast<double>(points.size());
        // Two interleaved halves, each from its own streams (the second's key past every texel's).
        halves[0].clear(), halves[1].clear();
        for (std::size_t s = 0; s < points.size(); ++s) halves[s % 2].push_back(points[s]);
        glm::dvec3 d(0.0), i(0.0), a(0.0), b(0.0);
        for (std::size_t h = 0; h < 2; ++h) {
          if (halves[h].empty()) continue;
          glm::dvec3 hd, hi;
          gather.leaving(halves[h], key + h * texels, hd, hi, cast[c], lights, !from_cache);
          const double w = static_cast<double>(halves[h].size()) / static_cast<double>(points.size());
          d += w * hd, i += w * hi;
          (h == 0 ? a : b) = from_cache ? hd : hd + hi;
        }
        if (from_cache) i = cached;
        const std::size_t k = static_cast<std::size_t>(key);
        m.direct.pixels[k] = glm::vec3(d), m.indirect.pixels[k] = glm::vec3(i), m.combined.pixels[k] = glm::vec3(d + i);
        glm::dvec3 se(0.0);
        if (!halves[1].empty())
          se = glm::abs(a - b) * std::sqrt(double(halves[0].size()) * double(halves[1].size())) / static_cast<double>(points.size());
        if (from_cache) se = glm::sqrt(se * se + cached_se * cached_se);
        m.error.pixels[k] = glm::vec3(se);
        cached_texels[c] += from_cache;
        m.coverage[k] = static_cast<float>(points.size()) / static_cast<float>(samples);
      }
    // Step 3: the empty texels from their chart's.
    dilate(m, atlas.owner, static_cast<uint32_t>(c), chart.x, chart.y, chart.x + chart.width, chart.y + chart.height);
  });
  if (seams) match_seams(m, atlas);
  for (uint64_t n : cast) m.rays += n;
  for (uint64_t n : cached_texels) m.cached += n;
  return m;
}

}  // namespace sirad
