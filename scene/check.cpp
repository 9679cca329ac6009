// sirad: the orientation checks of scene/check.h.
#include "scene/check.h"

#include <limits>
#include <map>
#include <numbers>

#include <fmt/format.h>

#include "scene/camera.h"
#include "scene/rays.h"

namespace sirad {

namespace {

// Per object and material: area-weighted fractions of the rays from the fronts of its faces
// that meet a front face (light exchanged), and of the rays from their backs that meet any face.
struct Sides {
  double area = 0, front_sees = 0, back_enclosed = 0;
  bool emits = false;
};

// Objects that look inside out and emitters that light nothing: one line each, naming the object
// (OBJ `o`/`g`) and material. A few cosine rays from both sides of (a sample of) the patches.
std::vector<std::string> orientation_warnings(const Scene& scene, const PatchMesh& mesh, const RayScene& rays) {
  constexpr std::size_t kMaxPatches = 20000;  // a sample of that many patches, evenly spaced
  constexpr int kRays = 16;                   // per side of a patch
  const double eps = ray_offset(mesh);
  std::map<std::pair<uint32_t, uint32_t>, Sides> parts;  // (object, material)
  const std::size_t stride = (mesh.size() + kMaxPatches - 1) / kMaxPatches;
  std::vector<std::array<double, 2>> pts, dirs;
  for (std::size_t j = 0; j < mesh.size(); j += stride) {
    const auto& t = mesh.patches[j];
    const glm::dvec3 a(mesh.vertices[t[0]]), b(mesh.vertices[t[1]]), c(mesh.vertices[t[2]]), n(mesh.normal[j]);
    Rng rng(7, j, 0, 3);
    stratified_square(kRays, rng, pts);
    stratified_square(kRays, rng, dirs);
    int sees = 0, enclosed = 0;
    for (int k = 0; k < kRays; ++k) {
      glm::dvec3 x = on_triangle(a, b, c, pts[static_cast<std::size_t>(k)][0], pts[static_cast<std::size_t>(k)][1]);
      glm::dvec3 d = cosine_direction(n, dirs[static_cast<std::size_t>(k)][0], dirs[static_cast<std::size_t>(k)][1]);
      sees += rays.seen(x + n * eps, d) >= 0;
      glm::dvec3 back = glm::reflect(d, n);  // the mirror direction, on the back side
      enclosed += rays.nearest(x - n * eps, back) >= 0;
    }
    const uint32_t object = mesh.source_triangle[j] < scene.triangles.size() ? scene.triangles[mesh.source_triangle[j]].object : 0;
    Sides& s = parts[{object, mesh.material[j]}];
    double w = mesh.area[j];
    s.area += w;
    s.front_sees += w * sees / kRays;
    s.back_enclosed += w * enclosed / kRays;
    s.emits = s.emits || mesh.emits(j);
  }
  std::vector<std::string> out;
  auto name = [&](uint32_t object, uint32_t material) {
    return fmt::format("object '{}' (material '{}')", object < scene.objects.size() ? scene.objects[object] : "(unnamed)",
                       mesh.materials[material].name);
  };
  for (const auto& [key, s] : parts) {
    double sees = s.front_sees / s.area, enclosed = s.back_enclosed / s.area;
    if (s.emits && sees < 0.01)
      out.push_back(fmt::format("{} emits but lights nothing: {:.0f} % of the light leaving its front meets a back "
                                "face or leaves the scene (turn it over, or make it two-sided)",
                                name(key.first, key.second), 100 * (1 - sees)));
    else if (sees < 0.1 && enclosed > 0.9)
      out.push_back(fmt::format("{} looks inside out: the fronts of its faces see almost nothing ({:.0f} % of their "
                                "rays meet a front face) while their backs are enclosed (flip its normals, or make "
                                "it two-sided)",
                                name(key.first, key.second), 100 * sees));
  }
  return out;
}

// A camera for a scene that carries none: of a few candidate views (framing the bounding box
// from outside along each horizontal axis, and from inside it near each upper corner looking
// across), the one whose view sees a front face on the most of 24 x 24 rays. Up is +Y, or +Z
// where the emitters face -Z (a Z-up export with ceiling lamps). `seen_share`: that share.
Camera choose_camera(const Scene& scene, const PatchMesh& mesh, const RayScene& rays, double& seen_share) {
  Camera fallback = default_camera(scene);
  // Up: +Z where the emitters' area-weighted normal points mostly along -Z, else +Y.
  glm::dvec3 lamp(0.0);
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) lamp += static_cast<double>(mesh.area[j]) * glm::dvec3(mesh.normal[j]);
  const int up_axis = (-lamp.z > std::abs(lamp.x) && -lamp.z > std::abs(lamp.y)) ? 2 : 1;
  glm::dvec3 up(0.0);
  up[up_axis] = 1.0;
  const int h1 = 0, h2 = up_axis == 1 ? 2 : 1;  // the horizontal axes
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const glm::vec3& v : mesh.vertices) {
    lo = glm::min(lo, glm::dvec3(v));
    hi = glm::max(hi, glm::dvec3(v));
  }
  const glm::dvec3 size = hi - lo, centre = 0.5 * (lo + hi);
  auto at = [&](double a, double b, double c) {  // a point of the box: fractions along h1, h2, up
    glm::dvec3 p = lo;
    p[h1] += a * size[h1];
    p[h2] += b * size[h2];
    p[up_axis] += c * size[up_axis];
    return p;
  };
  std::vector<Camera> candidates;
  const double radius = std::max(0.5 * glm::length(size), 1e-6);
  for (int axis : {h2, h1})
    for (double sign : {-1.0, 1.0}) {  // from outside, looking across the box (-h2 first: the old default)
      Camera c;
      c.vfov_deg = 40.0f;
      glm::dvec3 eye = centre;
      eye[axis] += sign * radius / std::sin(0.5 * c.vfov_deg * std::numbers::pi / 180.0);
      c.eye = glm::vec3(eye);
      c.look_at = glm::vec3(centre);
      c.up = glm::vec3(up);
      candidates.push_back(c);
    }
  for (double a : {0.15, 0.85})
    for (double b : {0.15, 0.85}) {  // from inside, near an upper corner, across to the far side
      Camera c;
      c.vfov_deg = 60.0f;
      c.eye = glm::vec3(at(a, b, 0.6));
      c.look_at = glm::vec3(at(1.0 - a, 1.0 - b, 0.35));
      c.up = glm::vec3(up);
      candidates.push_back(c);
    }
  constexpr int kSide = 24;
  Camera best = fallback;
  double best_share = -1.0;
  for (const Camera& c : candidates) {
    const CameraFrame frame = camera_frame(c, kSide, kSide);  // the pixel centres of a kSide x kSide image
    int hits = 0;
    for (int y = 0; y < kSide; ++y)
      for (int x = 0; x < kSide; ++x) hits += rays.seen(frame.eye, frame.direction(x + 0.5, y + 0.5)) >= 0;
    double share = static_cast<double>(hits) / (kSide * kSide);
    if (share > best_share + 1e-9) {
      best_share = share;
      best = c;
    }
  }
  seen_share = best_share;
  return best;
}

}  // namespace

SceneCheck check_scene(const Scene& scene, PatchMesh& mesh, const std::optional<Camera>& camera, const std::string& given_by) {
  SceneCheck out;
  out.warnings = scene.warnings;
  if (camera) {
    mesh.camera = camera;
    out.camera_from = given_by;
  } else if (mesh.camera) {
    out.camera_from = "the scene's";
  }
  if (mesh.size() == 0) {
    if (!mesh.camera) mesh.camera = default_camera(scene);
    return out;
  }
  if (mesh.camera) {
    const std::string what = camera ? given_by : scene.name + ": its camera";
    check_camera_reach(*mesh.camera, mesh.bound_center, mesh.bound_radius, what.c_str());
  }
  const RayScene rays(mesh, ray_offset(mesh), true);  // one quick build for both checks
  if (!mesh.camera) {
    double seen = 0.0;
    mesh.camera = choose_camera(scene, mesh, rays, seen);
    out.camera_from = fmt::format("chosen: it sees a surface on {:.0f} % of the view", 100 * seen);
  }
  for (std::string& w : orientation_warnings(scene, mesh, rays)) out.warnings.push_back(std::move(w));
  return out;
}

}  // namespace sirad
