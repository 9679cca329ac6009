// sirad: the orientation checks of core/scene_check.h.
#include "core/scene_check.h"

#include <map>

#include <fmt/format.h>

#include "core/rays.h"

namespace sirad {

namespace {

// Per object and material: area-weighted fractions of the rays from the fronts of its faces
// that meet a front face (light exchanged), and of the rays from their backs that meet any face.
struct Sides {
  double area = 0, front_sees = 0, back_enclosed = 0;
  bool emits = false;
};

}  // namespace

std::vector<std::string> orientation_warnings(const Scene& scene, const PatchMesh& mesh) {
  constexpr std::size_t kMaxPatches = 20000;  // a sample of that many patches, evenly spaced
  constexpr int kRays = 16;                   // per side of a patch
  if (mesh.size() == 0) return {};
  const double eps = 1e-5 * (static_cast<double>(mesh.bound_radius) + glm::length(glm::dvec3(mesh.bound_center)));
  RayScene rays(mesh, eps, true);
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
                                "face or leaves the scene (turn it over, or use --two-sided)",
                                name(key.first, key.second), 100 * (1 - sees)));
    else if (sees < 0.1 && enclosed > 0.9)
      out.push_back(fmt::format("{} looks inside out: the fronts of its faces see almost nothing ({:.0f} % of their "
                                "rays meet a front face) while their backs are enclosed (flip its normals, or use "
                                "--two-sided)",
                                name(key.first, key.second), 100 * sees));
  }
  return out;
}

std::vector<std::string> scene_warnings(const Scene& scene, const PatchMesh& mesh) {
  std::vector<std::string> out = scene.warnings;
  for (std::string& w : orientation_warnings(scene, mesh)) out.push_back(std::move(w));
  return out;
}

}  // namespace sirad
