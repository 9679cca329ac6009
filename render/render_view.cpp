// sirad: the camera view of a solution: corner radiosities and a z-buffer rasteriser.
#include "render/image.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "scene/camera.h"
#include "scene/rays.h"
#include "util/error.h"
#include "util/parallel.h"

namespace sirad {

namespace {

// A polygon corner in camera space (x right, y up, z depth along the view direction) with its
// radiosity; at most 4 after clipping a triangle against one plane.
struct ClipVertex {
  glm::dvec3 p;
  glm::dvec3 value;
};

// A corner projected for rasterising: pixel position, 1/depth and value/depth.
struct ScreenVertex {
  glm::dvec2 s;
  double inv_z;
  glm::dvec3 value_over_z;
};

// Sutherland-Hodgman against z >= z_near. The intersection on an edge is always computed from
// its inside to its outside corner, so two patches sharing the edge get the same point.
int clip_near(const std::array<ClipVertex, 3>& in, double z_near, std::array<ClipVertex, 4>& out) {
  int n = 0;
  for (int i = 0; i < 3; ++i) {
    const ClipVertex& a = in[i];
    const ClipVertex& b = in[(i + 1) % 3];
    const bool a_in = a.p.z >= z_near, b_in = b.p.z >= z_near;
    if (a_in) out[n++] = a;
    if (a_in != b_in) {
      const ClipVertex& inside = a_in ? a : b;
      const ClipVertex& outside = a_in ? b : a;
      const double t = (z_near - inside.p.z) / (outside.p.z - inside.p.z);
      out[n++] = {inside.p + t * (outside.p - inside.p),
                  inside.value + t * (outside.value - inside.value)};
    }
  }
  return n;
}

// Twice the signed area of (a, b, p). Evaluated with the endpoints in a canonical order, so
// the two patches sharing an edge get exactly opposite values: no pixel falls between them.
double edge(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& p) {
  const bool swap = b.x < a.x || (b.x == a.x && b.y < a.y);
  const glm::dvec2& u = swap ? b : a;
  const glm::dvec2& v = swap ? a : b;
  const double e = (v.x - u.x) * (p.y - u.y) - (v.y - u.y) * (p.x - u.x);
  return swap ? -e : e;
}

class Rasteriser {
 public:
  Rasteriser(int width, int height, glm::vec3 background)
      : width_(width),
        height_(height),
        depth_(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0.0) {
    image_.width = width;
    image_.height = height;
    image_.pixels.assign(depth_.size(), background);
  }

  // Draws one triangle; `flat` set means every pixel gets exactly that value.
  void triangle(const ScreenVertex& v0, const ScreenVertex& v1, const ScreenVertex& v2,
                const glm::dvec3* flat) {
    const double area = edge(v0.s, v1.s, v2.s);
    if (area == 0.0 || !std::isfinite(area)) return;  // degenerate on screen or NaN input
    const double sign = area > 0.0 ? 1.0 : -1.0;

    // Step 1: the pixels whose centres lie in the triangle's bounding box.
    const double min_x = std::min({v0.s.x, v1.s.x, v2.s.x}),
                 max_x = std::max({v0.s.x, v1.s.x, v2.s.x});
    const double min_y = std::min({v0.s.y, v1.s.y, v2.s.y}),
                 max_y = std::max({v0.s.y, v1.s.y, v2.s.y});
    const int x0 = static_cast<int>(std::clamp(std::ceil(min_x - 0.5), 0.0, double(width_)));
    const int x1 = static_cast<int>(std::clamp(std::floor(max_x - 0.5), -1.0, double(width_ - 1)));
    const int y0 = static_cast<int>(std::clamp(std::ceil(min_y - 0.5), 0.0, double(height_)));
    const int y1 = static_cast<int>(std::clamp(std::floor(max_y - 0.5), -1.0, double(height_ - 1)));

    // Step 2: inside test (edges inclusive), depth test on 1/z, perspective-correct value.
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const glm::dvec2 p{x + 0.5, y + 0.5};
        const double w0 = sign * edge(v1.s, v2.s, p);
        const double w1 = sign * edge(v2.s, v0.s, p);
        const double w2 = sign * edge(v0.s, v1.s, p);
        if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
        const double sum = w0 + w1 + w2;
        const double b0 = w0 / sum, b1 = w1 / sum, b2 = w2 / sum;
        const double inv_z = b0 * v0.inv_z + b1 * v1.inv_z + b2 * v2.inv_z;
        const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + x;
        if (!(inv_z > depth_[i])) continue;
        depth_[i] = inv_z;
        const glm::dvec3 value =
            flat != nullptr
                ? *flat
                : (b0 * v0.value_over_z + b1 * v1.value_over_z + b2 * v2.value_over_z) / inv_z;
        image_.pixels[i] = glm::vec3(value);
      }
    }
  }

  Image take() { return std::move(image_); }

 private:
  int width_, height_;
  std::vector<double> depth_;  // 1/z of the nearest surface so far; 0 = nothing
  Image image_;
};

}  // namespace

std::vector<std::array<glm::vec3, 3>> corner_radiosity(const PatchMesh& mesh,
                                                       const std::vector<glm::vec3>& radiosity) {
  const std::size_t n = mesh.size();
  if (radiosity.size() != n)
    fail("corner radiosity: {} radiosity values for {} patches", radiosity.size(), n);
  if (mesh.normal.size() != n || mesh.area.size() != n || mesh.material.size() != n)
    fail("corner radiosity: mesh has {} normals, {} areas, {} material ids for {} patches",
         mesh.normal.size(), mesh.area.size(), mesh.material.size(), n);

  // Step 1: vertex -> patches adjacency, compressed (offsets into one list).
  const std::size_t vertex_count = mesh.vertices.size();
  std::vector<uint32_t> offset(vertex_count + 1, 0);
  for (std::size_t j = 0; j < n; ++j)
    for (uint32_t v : mesh.patches[j]) {
      if (v >= vertex_count)
        fail("corner radiosity: patch {} refers to vertex {} of {}", j, v, vertex_count);
      ++offset[v + 1];
    }
  for (std::size_t v = 0; v < vertex_count; ++v) offset[v + 1] += offset[v];
  std::vector<uint32_t> adjacent(offset.back());
  std::vector<uint32_t> fill(offset.begin(), offset.end() - 1);
  for (std::size_t j = 0; j < n; ++j)
    for (uint32_t v : mesh.patches[j]) adjacent[fill[v]++] = static_cast<uint32_t>(j);

  // Step 2: per corner, the area-weighted mean over the compatible patches at that vertex; those
  // in one plane only if they see each other (the segment between their centres, lifted off the
  // surface, meets nothing: a wall standing on a floor between them, a zero-thickness one
  // included, keeps the two sides' light apart).
  const bool gaps = mesh.in_gap.size() == n;
  const float cos_limit = static_cast<float>(std::cos(30.0 * std::numbers::pi / 180.0));
  const float cos_flat = static_cast<float>(std::cos(1.0 * std::numbers::pi / 180.0));
  std::unique_ptr<RayScene> rays;  // none for a scene too far out to trace rays in: no sight test
  try {
    if (n > 0 && !mesh.vertices.empty()) rays = std::make_unique<RayScene>(mesh, 0.0, true);
  } catch (const Error&) {
    rays.reset();
  }
  const double lift = n > 0 ? ray_offset(mesh) : 0.0;
  const auto centre = [&](std::size_t j) {
    const auto& p = mesh.patches[j];
    return (glm::dvec3(mesh.vertices[p[0]]) + glm::dvec3(mesh.vertices[p[1]]) + glm::dvec3(mesh.vertices[p[2]])) / 3.0;
  };
  std::vector<std::array<glm::vec3, 3>> corners(n);
  const auto corners_of = [&](std::size_t j) {
    const glm::dvec3 up = glm::dvec3(mesh.normal[j]) * lift, from = centre(j) + up;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.patches[j][k];
      glm::dvec3 sum = glm::dvec3(radiosity[j]) * static_cast<double>(mesh.area[j]);
      double weight = mesh.area[j];
      for (uint32_t a = offset[v]; a < offset[v + 1]; ++a) {
        const uint32_t i = adjacent[a];
        if (i == j || mesh.material[i] != mesh.material[j] ||
            !(glm::dot(mesh.normal[i], mesh.normal[j]) >= cos_limit) || (gaps && mesh.in_gap[i] != mesh.in_gap[j]))
          continue;
        // Neighbours in one plane (within a degree) are checked to see each other; on a fold the
        // straight segment would cut through the surface itself, and no wall stands on a fold.
        if (rays && glm::dot(mesh.normal[i], mesh.normal[j]) >= cos_flat && rays->blocked(from, centre(i) + up)) continue;
        sum += glm::dvec3(radiosity[i]) * static_cast<double>(mesh.area[i]);
        weight += mesh.area[i];
      }
      corners[j][static_cast<std::size_t>(k)] = weight > 0.0 ? glm::vec3(sum / weight) : radiosity[j];
    }
  };
  parallel_for(n, 256, worker_threads(0), [&](std::size_t begin, std::size_t end, unsigned) {
    for (std::size_t j = begin; j < end; ++j) corners_of(j);
  });
  return corners;
}

Image render_view(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity,
                  const Camera& camera, int width, int height, Shading shading) {
  // Step 1: validate and set up the camera frame (scene/camera.h: the convention of every image).
  if (radiosity.size() != mesh.size())
    fail("cannot render view: {} radiosity values for {} patches", radiosity.size(), mesh.size());
  if (mesh.normal.size() != mesh.size())
    fail("cannot render view: {} normals for {} patches", mesh.normal.size(), mesh.size());
  const CameraFrame frame = camera_frame(camera, width, height);
  const glm::dvec3 eye = frame.eye, forward = frame.forward, right = frame.right, up = frame.up;

  // Step 2: every vertex in camera space once; the near plane relative to the scene's depth.
  std::vector<glm::dvec3> cam(mesh.vertices.size());
  double z_max = 0.0;
  for (std::size_t v = 0; v < cam.size(); ++v) {
    const glm::dvec3 d = glm::dvec3(mesh.vertices[v]) - eye;
    cam[v] = {glm::dot(d, right), glm::dot(d, up), glm::dot(d, forward)};
    if (cam[v].z > z_max) z_max = cam[v].z;
  }
  const double z_near = 1e-5 * z_max;
  const auto project = [&](const ClipVertex& c) {
    const auto [sx, sy] = frame.raster(c.p.x, c.p.y, c.p.z);
    return ScreenVertex{{sx, sy}, 1.0 / c.p.z, c.value / c.p.z};
  };

  std::vector<std::array<glm::vec3, 3>> corners;
  if (shading == Shading::gouraud) corners = corner_radiosity(mesh, radiosity);

  // Step 3: each front-facing patch, clipped at the near plane and fanned into triangles.
  Rasteriser raster(width, height, mesh.background);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& patch = mesh.patches[j];
    for (uint32_t v : patch)
      if (v >= cam.size())
        fail("cannot render view: patch {} refers to vertex {} of {}", j, v, cam.size());
    if (!(glm::dot(glm::dvec3(mesh.normal[j]), eye - glm::dvec3(mesh.vertices[patch[0]])) > 0.0))
      continue;  // back face (or edge-on)
    std::array<ClipVertex, 3> in;
    for (int k = 0; k < 3; ++k)
      in[k] = {cam[patch[k]],
               glm::dvec3(shading == Shading::gouraud ? corners[j][k] : radiosity[j])};
    std::array<ClipVertex, 4> clipped;
    const int count = clip_near(in, z_near, clipped);
    if (count < 3) continue;
    std::array<ScreenVertex, 4> s;
    for (int k = 0; k < count; ++k) s[k] = project(clipped[k]);
    const glm::dvec3 flat_value(radiosity[j]);
    const glm::dvec3* flat = shading == Shading::flat ? &flat_value : nullptr;
    for (int k = 1; k + 1 < count; ++k) raster.triangle(s[0], s[k], s[k + 1], flat);
  }
  return raster.take();
}

Image render_view_antialiased(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, const Camera& camera,
                              int width, int height, Shading shading, int samples_per_side) {
  const int s = samples_per_side;
  if (s < 1 || s > 16) fail("cannot render view: {} samples per pixel side (1..16)", s);
  if (s == 1) return render_view(mesh, radiosity, camera, width, height, shading);
  Image fine = render_view(mesh, radiosity, camera, width * s, height * s, shading);
  Image out;
  out.width = width;
  out.height = height;
  out.pixels.assign(static_cast<std::size_t>(width) * height, glm::vec3(0.0f));
  const float w = 1.0f / static_cast<float>(s * s);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      glm::vec3 sum(0.0f);
      for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) sum += fine.at(x * s + i, y * s + j);
      out.at(x, y) = sum * w;
    }
  return out;
}

}  // namespace sirad
