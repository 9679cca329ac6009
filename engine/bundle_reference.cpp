// sirad: the plain C++ reference of one bundle: simple, single-threaded, written for reading.
// Tests run it beside the OpenCL kernels, bundle for bundle. It follows the estimator of
// DESIGN.md section 1 directly: project every patch, list the patches each line crosses,
// sort each list by depth, and let every crossing gather its front neighbour. It uses the
// same coverage rule as the kernels (canonical edge functions, the same tie rule, the same
// float arithmetic without contraction) so the two agree line for line.
#include <algorithm>
#include <cmath>

#include "engine/bundle.h"

namespace sirad {

namespace {

struct Crossing {
  float depth;
  uint32_t patch;
  bool front_pos;  // the patch's normal points along +w
};

struct Projected {
  float x[3], y[3], z[3];  // counter-clockwise in the grid plane
  bool front_pos;
  bool visible;            // not seen edge-on
};

float edge_raw(float ax, float ay, float bx, float by, float px, float py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

// Canonical order of the endpoints, so neighbours sharing an edge get opposite values.
float edge_canonical(float ax, float ay, float bx, float by, float px, float py) {
  if (bx < ax || (bx == ax && by < ay)) return -edge_raw(bx, by, ax, ay, px, py);
  return edge_raw(ax, ay, bx, by, px, py);
}

bool inside(const Projected& p, float px, float py) {
  for (int k = 0; k < 3; ++k) {
    int k1 = (k + 1) % 3;
    float dx = p.x[k1] - p.x[k], dy = p.y[k1] - p.y[k];
    float e = edge_canonical(p.x[k], p.y[k], p.x[k1], p.y[k1], px, py);
    bool owns = e > 0.0f || (e == 0.0f && (dy < 0.0f || (dy == 0.0f && dx > 0.0f)));
    if (!owns) return false;
  }
  return true;
}

class ReferenceEngine final : public BundleEngine {
 public:
  explicit ReferenceEngine(const PatchMesh& mesh) : mesh_(mesh), vertices_(centred_vertices(mesh)) {}

  std::string description() const override { return "C++ reference (single-threaded)"; }

  void run(const SiradBundle& b, std::span<const glm::vec4> radiance, BundleResult& result) override {
    const std::size_t n = mesh_.size();
    const int grid = b.grid;

    // Project every patch onto the grid plane, counter-clockwise.
    std::vector<Projected> proj(n);
    for (std::size_t j = 0; j < n; ++j) {
      float X[3], Y[3], Z[3];
      for (int k = 0; k < 3; ++k) {
        glm::vec4 q = vertices_[mesh_.patches[j][k]];
        X[k] = (q.x * b.u[0] + q.y * b.u[1] + q.z * b.u[2]) * b.scale + b.offset_x;
        Y[k] = (q.x * b.v[0] + q.y * b.v[1] + q.z * b.v[2]) * b.scale + b.offset_y;
        Z[k] = q.x * b.w[0] + q.y * b.w[1] + q.z * b.w[2];
      }
      float area2 = edge_raw(X[0], Y[0], X[1], Y[1], X[2], Y[2]);
      Projected& p = proj[j];
      p.front_pos = area2 > 0.0f;
      int order[3] = {0, p.front_pos ? 1 : 2, p.front_pos ? 2 : 1};
      for (int k = 0; k < 3; ++k) {
        p.x[k] = X[order[k]];
        p.y[k] = Y[order[k]];
        p.z[k] = Z[order[k]];
      }
      p.visible = std::fabs(area2) > 0.0f;
    }

    // Every line (grid point) collects the patches it crosses, with their depth there.
    std::vector<std::vector<Crossing>> lines(static_cast<std::size_t>(grid) * grid);
    uint64_t crossings = 0;
    for (std::size_t j = 0; j < n; ++j) {
      const Projected& p = proj[j];
      if (!p.visible) continue;
      float a = std::fabs(edge_raw(p.x[0], p.y[0], p.x[1], p.y[1], p.x[2], p.y[2]));
      float dzdx = ((p.z[1] - p.z[0]) * (p.y[2] - p.y[0]) - (p.z[2] - p.z[0]) * (p.y[1] - p.y[0])) / a;
      float dzdy = ((p.z[2] - p.z[0]) * (p.x[1] - p.x[0]) - (p.z[1] - p.z[0]) * (p.x[2] - p.x[0])) / a;
      int xlo = std::max(0, static_cast<int>(std::ceil(std::min({p.x[0], p.x[1], p.x[2]}))));
      int xhi = std::min(grid - 1, static_cast<int>(std::floor(std::max({p.x[0], p.x[1], p.x[2]}))));
      int ylo = std::max(0, static_cast<int>(std::ceil(std::min({p.y[0], p.y[1], p.y[2]}))));
      int yhi = std::min(grid - 1, static_cast<int>(std::floor(std::max({p.y[0], p.y[1], p.y[2]}))));
      for (int y = ylo; y <= yhi; ++y)
        for (int x = xlo; x <= xhi; ++x) {
          float fx = static_cast<float>(x), fy = static_cast<float>(y);
          if (!inside(p, fx, fy)) continue;
          float depth = p.z[0] + dzdx * (fx - p.x[0]) + dzdy * (fy - p.y[0]);
          lines[static_cast<std::size_t>(y) * grid + x].push_back({depth, static_cast<uint32_t>(j), p.front_pos});
          ++crossings;
        }
    }

    // Sort each line by depth along +w, then order the faces at one place (depths within the
    // tie of the first of a run): those towards -w first, the later patch first, then those
    // towards +w, the later patch last (DESIGN.md section 1, "Coincident faces").
    auto rank = [](const Crossing& c) {
      return c.front_pos ? (uint64_t{1} << 32) | c.patch : (uint64_t{1} << 32) - 1 - c.patch;
    };
    for (auto& line : lines) {
      std::sort(line.begin(), line.end(), [](const Crossing& a, const Crossing& c) {
        if (a.depth != c.depth) return a.depth < c.depth;
        if (a.front_pos != c.front_pos) return !a.front_pos;
        return a.patch < c.patch;
      });
      for (std::size_t k = 0; k + 1 < line.size();) {
        std::size_t e = k + 1;
        while (e < line.size() && line[e].depth - line[k].depth <= b.depth_tie) ++e;
        std::stable_sort(line.begin() + static_cast<std::ptrdiff_t>(k), line.begin() + static_cast<std::ptrdiff_t>(e),
                         [&](const Crossing& a, const Crossing& c) { return rank(a) < rank(c); });
        k = e;
      }
    }

    // Gather, visiting lines in row-major order (the order each kernel work-item sums in).
    const glm::vec4 background(b.background[0], b.background[1], b.background[2], 0.0f);
    result.gathered.assign(n, glm::vec4(0.0f));
    result.hits.assign(n, 0);
    for (const auto& line : lines)
      for (std::size_t k = 0; k < line.size(); ++k) {
        const Crossing& c = line[k];
        glm::vec4 seen = background;
        // The front neighbour is the next crossing on the side the normal points to; it
        // counts only if it shows this patch its own front face.
        if (c.front_pos && k + 1 < line.size() && !line[k + 1].front_pos)
          seen = radiance[line[k + 1].patch];
        if (!c.front_pos && k > 0 && line[k - 1].front_pos) seen = radiance[line[k - 1].patch];
        result.gathered[c.patch] += glm::vec4(glm::vec3(seen), 0.0f);
        result.hits[c.patch] += 1;
      }
    result.crossings = crossings;
  }

 private:
  const PatchMesh& mesh_;
  std::vector<glm::vec4> vertices_;
};

}  // namespace

std::unique_ptr<BundleEngine> make_reference_engine(const PatchMesh& mesh) {
  return std::make_unique<ReferenceEngine>(mesh);
}

}  // namespace sirad
