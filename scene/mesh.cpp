// sirad: meshing: regular n x n subdivision of input triangles, exact vertex welding, content hash.
#include "scene/mesh.h"

#include <xxhash.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <new>

#include "scene/contacts.h"
#include "util/error.h"
#include "util/polygon.h"

namespace sirad {
namespace {

constexpr uint64_t kMaxPatches = 0x7fffffff;  // 2^31 - 1
// Patch counts saturate here (well above kMaxPatches, far below uint64 overflow).
constexpr uint64_t kSaturated = uint64_t{1} << 40;

double longest_edge(const Triangle& t) {
  const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
  return std::sqrt(
      std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)}));
}

// The length a triangle is subdivided by: its longest edge, but for a sliver (longest^2 over
// 16 x its area) 4 x the square root of its area, so that its n x n pieces, slivers of the same
// shape, are no smaller in area than about a quarter of a well-shaped patch's: a patch's noise
// grows as its area shrinks, and the slivers beside a lamp's strips (scene/gap_cuts.cpp) or a
// Boolean's cut gained nothing from being cut to zero area in float. Triangles of any better
// shape (equilateral, right-angled) are unaffected.
double subdivision_length(const Triangle& t) {
  const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
  const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
  return std::min(longest_edge(t), 4.0 * std::sqrt(area));
}

// A patch is split along at most this many pieces' worth of contact segments, and not where a
// piece would reach less than this fraction of its size beyond the cut (a contact along its
// edge, moved a hair inside by float rounding; a foot that grazes its corner).
constexpr std::size_t kMaxPiecesPerPatch = 8;
constexpr double kLeastCut = 1e-3;
// A grid, and a first meshing for a target, may pass the limit on patches by this factor (the
// splits drop pieces inside solids and add others, and a target's grid is then made coarser by
// what they added; mesh_scene): the final meshing may not.
constexpr uint64_t kSplitHeadroom = 4;

// Subdivisions per edge: n = max(1, ceil(length / max_edge)), `length` a triangle's
// subdivision_length; max_edge 0 means none.
uint64_t subdivisions(double length, double max_edge) {
  if (max_edge == 0.0) return 1;
  const double n = std::ceil(length / max_edge);
  if (!(n < double(uint64_t{1} << 20))) return uint64_t{1} << 20;  // n^2 alone saturates
  return std::max<uint64_t>(1, static_cast<uint64_t>(n));
}

// Total patches for `max_edge`, saturating at kSaturated. Monotone non-increasing in max_edge.
uint64_t patch_count(const std::vector<double>& lengths, double max_edge) {
  uint64_t total = 0;
  for (double l : lengths) {
    const uint64_t n = subdivisions(l, max_edge);
    total = std::min(kSaturated, total + n * n);
  }
  return total;
}

// The max_edge whose patch count is closest to `target` (ties: the smaller count), found by
// bisection over the bit patterns of positive doubles (ordered like their values).
double max_edge_for_target(const std::vector<double>& lengths, uint64_t target) {
  const double top = *std::max_element(lengths.begin(), lengths.end());
  if (!(top > 0.0)) return 0.0;  // every triangle stays whole
  // count(hi) = number of triangles <= target; count(lo) > target since its n for the
  // triangle of the greatest length exceeds sqrt(target).
  double hi = top;
  double lo = top / (std::ceil(std::sqrt(double(target))) + 1.0);
  uint64_t lo_bits = std::bit_cast<uint64_t>(lo), hi_bits = std::bit_cast<uint64_t>(hi);
  while (hi_bits - lo_bits > 1) {
    const uint64_t mid = lo_bits + (hi_bits - lo_bits) / 2;
    if (patch_count(lengths, std::bit_cast<double>(mid)) > target)
      lo_bits = mid;
    else
      hi_bits = mid;
  }
  lo = std::bit_cast<double>(lo_bits);
  hi = std::bit_cast<double>(hi_bits);
  // Adjacent doubles: count(lo) is the smallest count above target, count(hi) the largest
  // at or below it.
  return patch_count(lengths, lo) - target < target - patch_count(lengths, hi) ? lo : hi;
}

// Exact float bit pattern of a position, -0.0 folded into 0.0: the welding key.
using Key = std::array<uint32_t, 3>;

uint32_t float_bits(float f) { return f == 0.0f ? 0u : std::bit_cast<uint32_t>(f); }

Key key_of(const glm::vec3& p) { return {float_bits(p.x), float_bits(p.y), float_bits(p.z)}; }

// Welds positions by exact bit pattern: an open-addressing hash table (linear probing, load
// at most 1/2) of indices into `vertices`, which receives new positions in order of first use.
class Welder {
 public:
  Welder(std::vector<glm::vec3>& vertices, const std::string& name, std::size_t expected)
      : vertices_(vertices), name_(name) {
    resize(std::bit_ceil(std::max<std::size_t>(1024, 2 * expected)));
  }

  uint32_t operator()(const glm::vec3& p) {
    const Key key = key_of(p);
    if (2 * (vertices_.size() + 1) > slots_.size()) resize(2 * slots_.size());
    for (std::size_t s = hash(key);; s = (s + 1) & mask_) {
      if (slots_[s] == kEmpty) {
        if (vertices_.size() >= kEmpty) fail("{}: mesh has more than 2^32 - 1 vertices", name_);
        slots_[s] = static_cast<uint32_t>(vertices_.size());
        vertices_.push_back({std::bit_cast<float>(key[0]), std::bit_cast<float>(key[1]),
                             std::bit_cast<float>(key[2])});
        return slots_[s];
      }
      if (key_of(vertices_[slots_[s]]) == key) return slots_[s];
    }
  }

 private:
  static constexpr uint32_t kEmpty = std::numeric_limits<uint32_t>::max();

  std::size_t hash(const Key& key) const { return XXH3_64bits(key.data(), sizeof key) & mask_; }

  void resize(std::size_t size) {
    slots_.assign(size, kEmpty);
    mask_ = size - 1;
    for (uint32_t i = 0; i < vertices_.size(); ++i) {
      std::size_t s = hash(key_of(vertices_[i]));
      while (slots_[s] != kEmpty) s = (s + 1) & mask_;
      slots_[s] = i;
    }
  }

  std::vector<glm::vec3>& vertices_;
  const std::string& name_;
  std::vector<uint32_t> slots_;
  std::size_t mask_ = 0;
};

bool lex_less(const glm::vec3& a, const glm::vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// The point k/n of the way from p to q, computed canonically: from the lexicographically
// smaller endpoint, in double, so both triangles sharing the edge get the same float bits.
glm::vec3 edge_point(glm::vec3 p, glm::vec3 q, uint64_t k, uint64_t n) {
  if (k == 0) return p;
  if (k == n) return q;
  if (lex_less(q, p)) {
    std::swap(p, q);
    k = n - k;
  }
  const glm::dvec3 lo(p), hi(q);
  return glm::vec3(lo + (hi - lo) * (double(k) / double(n)));
}

// Grid point (i, j) of triangle abc split n ways: a + (i/n)(b - a) + (j/n)(c - a).
glm::vec3 grid_point(const Triangle& t, uint64_t i, uint64_t j, uint64_t n) {
  const auto& [a, b, c] = t.p;
  if (j == 0) return edge_point(a, b, i, n);
  if (i == 0) return edge_point(a, c, j, n);
  if (i + j == n) return edge_point(b, c, j, n);
  const double w = 1.0 / double(n);
  return glm::vec3(glm::dvec3(a) * (double(n - i - j) * w) + glm::dvec3(b) * (double(i) * w) +
                   glm::dvec3(c) * (double(j) * w));
}

// Appends the n*n patches of triangle `t` (index `ti`). Order: rows j = 0..n-1 from edge ab
// towards c; in each row from the a side, alternately the upright sub-triangle
// (i,j),(i+1,j),(i,j+1) and the inverted one (i+1,j),(i+1,j+1),(i,j+1). Both keep the
// parent's orientation.
void subdivide(const Scene& scene, uint32_t ti, uint64_t n, Welder& weld, PatchMesh& mesh,
               std::vector<uint32_t>& grid, const std::vector<ContactSegment>& contacts, CoverTest& cover) {
  const Triangle& t = scene.triangles[ti];
  // Step 1: weld the (n+1)(n+2)/2 grid points, row by row.
  grid.clear();
  for (uint64_t j = 0; j <= n; ++j)
    for (uint64_t i = 0; i + j <= n; ++i) grid.push_back(weld(grid_point(t, i, j, n)));
  const auto at = [&](uint64_t i, uint64_t j) { return grid[j * (n + 1) - j * (j - 1) / 2 + i]; };
  // Step 2: emit the sub-triangles with their normal and area (double precision).
  const auto emit = [&](uint32_t a, uint32_t b, uint32_t c) {
    const glm::dvec3 pa(mesh.vertices[a]), pb(mesh.vertices[b]), pc(mesh.vertices[c]);
    const glm::dvec3 cross = glm::cross(pb - pa, pc - pa);
    const double length = glm::length(cross);
    const auto area = static_cast<float>(0.5 * length);
    if (!(area > 0.0f) || !std::isfinite(area)) {
      if (t.source_line > 0)
        fail("{}: triangle {} (line {}): a patch has zero or non-finite area in float", scene.name,
             ti, t.source_line);
      fail("{}: triangle {}: a patch has zero or non-finite area in float", scene.name, ti);
    }
    mesh.patches.push_back({a, b, c});
    mesh.normal.push_back(glm::vec3(cross / length));
    mesh.area.push_back(area);
    mesh.material.push_back(t.material);
    mesh.source_triangle.push_back(ti);
  };
  // A sub-triangle that a contact segment crosses is split along it (convex pieces, each a fan):
  // no patch straddles the foot of a wall. A piece inside the solid that stands there (under the
  // wall), or a whole sub-triangle there, is left out: no light reaches it, and it would cost
  // patches. So are fan triangles too thin to have an area in float (holes of about 1e-9 of the
  // patch).
  const glm::dvec3 normal = glm::normalize(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0])));
  std::vector<std::vector<glm::dvec3>> pieces, next;
  std::vector<glm::dvec3> in, out;
  const auto put = [&](uint32_t a, uint32_t b, uint32_t c) {
    const std::array<glm::dvec3, 3> sub = {glm::dvec3(mesh.vertices[a]), glm::dvec3(mesh.vertices[b]), glm::dvec3(mesh.vertices[c])};
    pieces.assign(1, {sub[0], sub[1], sub[2]});
    const double size = std::sqrt(glm::length(glm::cross(sub[1] - sub[0], sub[2] - sub[0])));  // about an edge
    for (const ContactSegment& s : contacts) {
      glm::dvec3 p = s.p, q = s.q;
      if (pieces.size() >= kMaxPiecesPerPatch || !clip_to_triangle(sub, normal, p, q) || !(glm::length(q - p) > 1e-6 * size)) continue;
      const glm::dvec3 m = glm::normalize(glm::cross(normal, q - p));
      next.clear();
      for (const auto& piece : pieces) {
        double over = 0.0, under = 0.0;  // how far the piece reaches either side of the cut
        for (const glm::dvec3& u : piece) over = std::max(over, glm::dot(u - p, m)), under = std::max(under, -glm::dot(u - p, m));
        if (!(std::min(over, under) > kLeastCut * size)) {
          next.push_back(piece);  // along its edge, or a sliver of it
          continue;
        }
        split_convex(piece, p, m, in, out);
        if (in.size() >= 3 && out.size() >= 3) {
          next.push_back(in);
          next.push_back(out);
        } else {
          next.push_back(piece);
        }
      }
      std::swap(pieces, next);
    }
    for (const auto& piece : pieces) {
      glm::dvec3 centre(0.0);
      for (const glm::dvec3& x : piece) centre += x;
      if (!contacts.empty() && cover.inside(ti, contacts, centre / static_cast<double>(piece.size()))) continue;
      if (pieces.size() == 1) {
        emit(a, b, c);
        return;
      }
      for (std::size_t k = 1; k + 1 < piece.size(); ++k) {
        const uint32_t u = weld(glm::vec3(piece[0])), v = weld(glm::vec3(piece[k])), w = weld(glm::vec3(piece[k + 1]));
        const glm::dvec3 pu(mesh.vertices[u]), pv(mesh.vertices[v]), pw(mesh.vertices[w]);
        const glm::dvec3 cross = glm::cross(pv - pu, pw - pu);
        if (u == v || v == w || u == w || !(static_cast<float>(0.5 * glm::length(cross)) > 0.0f) || !(glm::dot(cross, normal) > 0.0))
          continue;
        emit(u, v, w);
      }
    }
  };
  for (uint64_t j = 0; j < n; ++j)
    for (uint64_t i = 0; i + j < n; ++i) {
      put(at(i, j), at(i + 1, j), at(i, j + 1));
      if (i + j + 1 < n) put(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
    }
}

// Bounding sphere: AABB centre, radius the largest vertex distance (double), enlarged by
// 1e-6 relative and rounded up so every vertex lies strictly inside.
void bound(PatchMesh& mesh, const std::string& name) {
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const glm::vec3& v : mesh.vertices) {
    lo = glm::min(lo, glm::dvec3(v));
    hi = glm::max(hi, glm::dvec3(v));
  }
  mesh.bound_center = glm::vec3(0.5 * (lo + hi));
  double radius = 0.0;
  for (const glm::vec3& v : mesh.vertices)
    radius = std::max(radius, glm::length(glm::dvec3(v) - glm::dvec3(mesh.bound_center)));
  radius *= 1.0 + 1e-6;
  if (!(radius < double(std::numeric_limits<float>::max())))
    fail("{}: scene extent too large", name);
  mesh.bound_radius = static_cast<float>(radius);
  if (double(mesh.bound_radius) <= radius)
    mesh.bound_radius = std::nextafter(mesh.bound_radius, std::numeric_limits<float>::infinity());
}

// Canonical little-endian bytes fed to a streaming XXH3-128.
class Hasher {
 public:
  Hasher() : state_(XXH3_createState(), &XXH3_freeState) {
    if (!state_ || XXH3_128bits_reset(state_.get()) != XXH_OK) throw std::bad_alloc();
  }
  void bytes(const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    buffer_.insert(buffer_.end(), p, p + size);
    if (buffer_.size() >= (1 << 16)) flush();
  }
  void u32(uint32_t v) {
    const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                                static_cast<unsigned char>(v >> 16),
                                static_cast<unsigned char>(v >> 24)};
    bytes(b, 4);
  }
  void u64(uint64_t v) {
    u32(static_cast<uint32_t>(v));
    u32(static_cast<uint32_t>(v >> 32));
  }
  void f32(float f) { u32(float_bits(f)); }
  void vec(const glm::vec3& v) {
    f32(v.x);
    f32(v.y);
    f32(v.z);
  }
  std::string hex() {
    flush();
    XXH128_canonical_t canonical;
    XXH128_canonicalFromHash(&canonical, XXH3_128bits_digest(state_.get()));
    static constexpr char kDigits[] = "0123456789abcdef";
    std::string out;
    for (unsigned char b : canonical.digest) {
      out += kDigits[b >> 4];
      out += kDigits[b & 15];
    }
    return out;
  }

 private:
  void flush() {
    XXH3_128bits_update(state_.get(), buffer_.data(), buffer_.size());
    buffer_.clear();
  }
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state_;
  std::vector<unsigned char> buffer_;
};

}  // namespace

// The range of values the solver carries. The transport sums, per patch and bundle, up to
// grid^2 (at most 8192^2 = 6.7e7) radiosities in 32-bit floats (FLT_MAX 3.4e38), and radiosity
// is at most E / (1 - rho), 1e3 E at rho = 0.999: an emission of at most 1e20 keeps the largest
// sum near 6.7e30, seven decades short of overflow (an emission of 1e38 gave NaN). Below 1e-20,
// a scene's brightest light makes radiosities that lose their precision in float (denormals
// from 1.2e-38). Power (emission x area) up to 1e30 keeps a first shot's products finite.
namespace {

constexpr double kMaxEmission = 1e20, kMinBrightest = 1e-20, kMaxPower = 1e30;

void check_radiometry(const Scene& scene) {
  double brightest = 0;
  auto value = [&](const glm::vec3& v, const std::string& what, double hi) {
    for (int k = 0; k < 3; ++k)
      if (!(v[k] >= 0.0f && v[k] <= static_cast<float>(hi)))  // the bound as a float: 1e20f is just above 1e20
        fail("{}: {} component {} is {}, outside [0, {:.0e}]", scene.name, what, k, v[k], hi);
  };
  for (const Material& m : scene.materials) {
    value(m.reflectance, fmt::format("material '{}': reflectance", m.name.substr(0, 64)), 1.0);
    value(m.emission, fmt::format("material '{}': emission", m.name.substr(0, 64)), kMaxEmission);
    brightest = std::max<double>({brightest, m.emission.x, m.emission.y, m.emission.z});
  }
  value(scene.background, "background", kMaxEmission);
  if (brightest > 0 && brightest < kMinBrightest)
    fail("{}: the brightest emission is {:.3g}, below {:.0e}: scale the scene's emission up", scene.name, brightest, kMinBrightest);
}

// The options and the scene checked; each triangle's subdivision_length (0: it stays one patch).
std::vector<double> checked_lengths(const Scene& scene, const MeshOptions& options) {
  if (std::isnan(options.max_edge) || options.max_edge < 0.0)
    fail("{}: max_edge {} must be a positive length", scene.name, options.max_edge);
  if (options.target_patches > 0 && options.max_edge > 0.0)
    fail("{}: set target_patches or max_edge, not both", scene.name);
  if (options.target_patches > kMaxPatches)
    fail("{}: target of {} patches exceeds 2^31 - 1", scene.name, options.target_patches);
  if (scene.triangles.empty()) fail("{}: scene has no triangles", scene.name);
  check_radiometry(scene);
  std::vector<double> lengths;
  lengths.reserve(scene.triangles.size());
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const Triangle& t = scene.triangles[i];
    for (const glm::vec3& p : t.p)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        fail("{}: triangle {} has a non-finite vertex", scene.name, i);
    if (t.material >= scene.materials.size())
      fail("{}: triangle {} has material {} of {}", scene.name, i, t.material,
           scene.materials.size());
    lengths.push_back(t.unlit || t.whole ? 0.0 : subdivision_length(t));  // a face no light reaches, or a strip along a gap, stays one patch
  }
  return lengths;
}

// What the mesh carries of its scene (materials, objects, the gap's marks, background, camera),
// its bounds, and each patch's emitted power checked.
void finish_mesh(const Scene& scene, PatchMesh& mesh) {
  if (std::any_of(scene.triangles.begin(), scene.triangles.end(), [](const Triangle& t) { return t.in_gap; })) {
    mesh.in_gap.resize(mesh.size());
    for (std::size_t j = 0; j < mesh.size(); ++j) mesh.in_gap[j] = scene.triangles[mesh.source_triangle[j]].in_gap ? 1 : 0;
  }
  mesh.materials = scene.materials;
  mesh.objects = scene.objects;
  mesh.triangle_object.resize(scene.triangles.size());
  for (std::size_t i = 0; i < scene.triangles.size(); ++i)
    mesh.triangle_object[i] = scene.triangles[i].object < scene.objects.size() ? scene.triangles[i].object : 0;
  if (mesh.objects.empty()) mesh.objects.push_back("(unnamed)");
  mesh.background = scene.background;
  mesh.camera = scene.camera;
  bound(mesh, scene.name);
  // Each patch's emitted power within the float pipeline's range too (see check_radiometry).
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const glm::vec3& e = mesh.materials[mesh.material[j]].emission;
    const double power = static_cast<double>(std::max({e.x, e.y, e.z})) * mesh.area[j];
    if (power > kMaxPower)
      fail("{}: patch {} emits {:.3g} (emission x area), more than {:.0e}: scale the scene's units or its emission down",
           scene.name, j, power, kMaxPower);
  }
}

}  // namespace

PatchMesh mesh_scene(const Scene& scene, const MeshOptions& options) {
  // Step 1: options and input.
  const std::vector<double> lengths = checked_lengths(scene, options);

  // Step 2: where faces meet, along which patches are split (none when each face stays one
  // patch: the meshes of the load-time helpers, which must match their faces one to one).
  const bool whole_faces = options.target_patches == 0 && options.max_edge == 0.0;
  const double tolerance = contact_tolerance(scene);
  const std::vector<std::vector<ContactSegment>> contacts =
      whole_faces ? std::vector<std::vector<ContactSegment>>(scene.triangles.size()) : contact_segments(scene, tolerance);

  // Step 3: for an edge length, the grid's patch count checked before anything is allocated,
  // then subdivide, split and weld, in input triangle order.
  const uint64_t limit = options.max_patches > 0 ? options.max_patches : kMaxPatches;
  const auto grid_mesh = [&](double max_edge) {
    CoverTest cover(scene, tolerance);
    const uint64_t total = patch_count(lengths, max_edge);
    if (total > kMaxPatches)
      fail("{}: meshing would make {}{} patches, more than 2^31 - 1", scene.name,
           total == kSaturated ? "over " : "", total);
    if (options.max_patches > 0 && total > kSplitHeadroom * options.max_patches)
      fail("{}: meshing would make {} patches, more than the {} allowed", scene.name, total, options.max_patches);
    PatchMesh mesh;
    try {
      mesh.patches.reserve(total);
      mesh.normal.reserve(total);
      mesh.area.reserve(total);
      mesh.material.reserve(total);
      mesh.source_triangle.reserve(total);
      // About one vertex per two patches, plus the corners and edges of each input triangle.
      Welder weld(mesh.vertices, scene.name, total / 2 + 3 * scene.triangles.size());
      std::vector<uint32_t> grid;
      for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
        subdivide(scene, static_cast<uint32_t>(i), subdivisions(lengths[i], max_edge), weld, mesh,
                  grid, contacts[i], cover);
        if (mesh.size() > kSplitHeadroom * limit)
          fail("{}: split where faces meet, the meshing makes more than {} patches", scene.name, kSplitHeadroom * limit);
      }
    } catch (const std::bad_alloc&) {
      fail("{}: out of memory meshing {} patches", scene.name, total);
    }
    return mesh;
  };
  double max_edge = options.max_edge;
  if (options.target_patches > scene.triangles.size())
    max_edge = max_edge_for_target(lengths, options.target_patches);
  PatchMesh mesh = grid_mesh(max_edge);
  // A target counts the patches the splits add and the cover leaves out: the grid is made
  // coarser (or finer) once by as many. The second grid's cells cross the contacts a little less
  // (or more) often, so the count ends near the target, not on it.
  const auto added = static_cast<int64_t>(mesh.size()) - static_cast<int64_t>(patch_count(lengths, max_edge));
  const auto regrid = static_cast<int64_t>(options.target_patches) - added;
  if (options.target_patches > scene.triangles.size() && added != 0 && regrid > static_cast<int64_t>(scene.triangles.size())) {
    const double other = max_edge_for_target(lengths, static_cast<uint64_t>(regrid));
    if (other != max_edge) mesh = grid_mesh(other);
  }
  if (mesh.size() > limit)
    fail("{}: split where faces meet, the meshing makes {} patches, more than {}", scene.name, mesh.size(), limit);

  // Step 4: scene data, bounds and the content hash.
  finish_mesh(scene, mesh);
  mesh.hash = content_hash(mesh);
  return mesh;
}

std::string content_hash(const PatchMesh& mesh) {
  Hasher h;
  static constexpr char kTag[] = "sirad-mesh-v1";
  h.bytes(kTag, sizeof kTag - 1);
  h.u64(mesh.vertices.size());
  h.u64(mesh.patches.size());
  h.u64(mesh.materials.size());
  for (const glm::vec3& v : mesh.vertices) h.vec(v);
  for (const auto& p : mesh.patches)
    for (uint32_t v : p) h.u32(v);
  for (uint32_t m : mesh.material) h.u32(m);
  for (const Material& m : mesh.materials) {
    h.vec(m.reflectance);
    h.vec(m.emission);
  }
  h.vec(mesh.background);
  return h.hex();
}

}  // namespace sirad
