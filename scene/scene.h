// sirad: the scene as imported (triangles with diffuse materials and a camera) and the
// ways to get one: OBJ+MTL files and the built-in scenes `cornell` and `furnace`.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace sirad {

// A diffuse material. Units are radiance (DESIGN.md section 1): `emission` is emitted radiance
// (MTL Ke), `reflectance` the diffuse albedo per channel in [0, 1] (MTL Kd).
struct Material {
  std::string name;
  glm::vec3 reflectance{0.0f};
  glm::vec3 emission{0.0f};
  // Both sides of its faces receive, reflect and emit, as Cycles treats every mesh (MTL
  // `sirad_two_sided 1`, or --two-sided for all): load_scene gives each such triangle a
  // reversed twin at the same place (DESIGN.md section 1, "Two-sided surfaces").
  bool two_sided = false;
  // Whether it emits: any channel of its emission above zero.
  bool emits() const { return emission.x > 0.0f || emission.y > 0.0f || emission.z > 0.0f; }
};

// A pinhole camera. `vfov_deg` is the full vertical field of view; the image aspect comes from
// the output size.
struct Camera {
  glm::vec3 eye{0.0f};
  glm::vec3 look_at{0.0f, 0.0f, 1.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vfov_deg = 40.0f;
};

// A face's place in the file's own lightmap UV set (glTF TEXCOORD_1), as an affine map of its
// plane: uv(p) = uv0 + (mu . (p - origin), mv . (p - origin)). A piece cut from the face keeps
// the face's map, so its corners land where the file put those points; a point off the plane
// maps as its projection onto it.
struct UvMap {
  glm::dvec3 origin{0.0}, mu{0.0}, mv{0.0};
  glm::dvec2 uv0{0.0};
  glm::dvec2 at(const glm::dvec3& p) const;
};

// The map that puts corners p[k] at uv[k]; false (and `out` untouched) where either triangle
// has no area.
bool make_uv_map(const std::array<glm::dvec3, 3>& p, const std::array<glm::dvec2, 3>& uv, UvMap& out);

inline constexpr uint32_t kNoUvMap = 0xffffffffu;

// One input triangle, counter-clockwise seen from its front (the side its normal points to).
struct Triangle {
  std::array<glm::vec3, 3> p;
  uint32_t material = 0;  // index into Scene::materials
  uint32_t source_line = 0;  // 1-based line of the face in its file (0 if not from a file)
  uint32_t object = 0;       // index into Scene::objects
  // No light reaches its front (mark_unlit_faces): the mesher leaves it one patch, so that the
  // patch budget goes to the surfaces light reaches. Only the meshing depends on it.
  bool unlit = false;
  // A piece of a face over an emitter, or another surface, across a small gap (cut_along_gaps):
  // the light trapped in the gap, or the shadow there. Outputs and the final gather do not blend
  // its values with the face's beyond the outline (corner_radiosity); the solve does not depend
  // on it.
  bool in_gap = false;
  // A strip along the rim of such a gap, on either face or on the emitter (cut_along_gaps):
  // its width is set by the gap, so the mesher leaves it whole, one patch however long.
  bool whole = false;
  // The reversed twin of a face of a two-sided material (add_back_faces).
  bool back = false;
  // Its face's map in Scene::uv_maps, or kNoUvMap where the file gives none.
  uint32_t uv_map = kNoUvMap;
};

struct Scene {
  std::string name;                 // built-in name or file path, for messages
  std::vector<Material> materials;
  std::vector<Triangle> triangles;
  // The file's lightmap UV maps (Triangle::uv_map; glTF TEXCOORD_1). Neither they nor
  // Triangle::back travel in encode_scene: only the bake reads them.
  std::vector<UvMap> uv_maps;
  // The lightmap's size in texels (width, height) where the file names it (a glb sirad baked:
  // its asset's sirad_lightmap), so that a rebake keeps its texels where they were.
  std::optional<std::array<int, 2>> lightmap_size;
  std::optional<Camera> camera;     // from the file's `# sirad camera` line or built-in
  // The camera's width / height where the file says (glTF aspectRatio): the default image shape.
  std::optional<double> camera_aspect;
  glm::vec3 background{0.0f};       // radiance seen by a line that leaves the scene
  // Object names (OBJ `o` or `g`; "(unnamed)" before any), for messages about parts of a scene.
  std::vector<std::string> objects{"(unnamed)"};
  // What the importer read but does not use (a texture map, ...), one line each, to be shown.
  std::vector<std::string> warnings;
};

struct ImportOptions {
  // Zero-area triangles are an error by default (bad input); with this they are dropped.
  bool skip_degenerate = false;
  // Every material two-sided (Material::two_sided), whatever the file says.
  bool two_sided = false;
  // A glTF's relative URIs may name files outside its folder (../textures/a.png); by default
  // only files in its folder and below are read.
  bool outside_uris = false;
};

// Loads `spec`: a built-in name ("cornell", "furnace", "bright-room", "three-lights") or a path to an .obj file (its .mtl
// files resolved next to it). Validates everything: finite coordinates, indices in range,
// known materials, reflectance in [0, 1], finite non-negative emission, at least one
// triangle and at least one emitter. Throws sirad::Error naming file and line.
Scene load_scene(const std::string& spec, const ImportOptions& options = {});

// Parses OBJ text (with its MTL files provided by name) without touching the file system.
// `name` is used in error messages. Used for the built-in scenes and by tests.
Scene parse_obj(const std::string& name, const std::string& obj_text,
                const std::vector<std::pair<std::string, std::string>>& mtl_files,
                const ImportOptions& options = {});

// Gives triangles of two-sided materials a reversed twin (same place, opposite normal, same
// material): each side then has a value of its own, as in Cycles. Only twins whose side can
// exchange light are kept (a few cosine rays from each meet an original's front or an emitter's:
// not the inside of a solid, not a side facing into nothing, not one covered by an original at
// its place), and they come before all original triangles, so that an original is on top of a
// twin at one place (scene/two_sided.cpp; DESIGN.md section 1, "Two-sided surfaces").
void add_back_faces(Scene& scene);

// Cuts every face that faces an emitter across a gap of at most kGapCut times the emitter's
// extent (a ceiling 1-2 cm above a lamp's upper side) along the emitter's outline (a convex
// lamp surface's rim, else each emitting triangle's edges), so that no patch averages the light
// trapped in the gap with the light outside it. Where the gap g is at least kGapStripsFrom of
// the emitter's extent, strips along the rim are cut too: on the face, along the outline moved
// out by kGapStripsOut x g and in by kGapStripsIn x g; on the emitter, along its outline moved
// in by kGapStripsEmitter x g (each list ascending; the last is the strips' far edge). The
// radiosity in a gap falls off towards its rim within a few gap heights, the light that leaves
// the gap is the rim's, and the ceiling just outside the slit sends part of its light back in,
// so a patch that averages either band with what lies beyond sends too much light into the room
// (scene/gap_cuts.cpp; DESIGN.md section 1, "Light in gaps"). Strips are Triangle::whole. The
// pieces keep the face's material, object and line (at most about 1024 pieces a face). Scenes
// with more than kMaxGapCutPairs (emitter, face) pairs are left as they are.
// Every face that faces another surface (its front or its back) across a gap of at most
// kGapCutSurface times that surface's extent (a wall 5 cm behind a wardrobe's back, a floor
// under a rug or a sofa) is cut along its outline too, so that no patch averages the light of the
// room with the shadow in the gap; and so is a face that another surface lies on, within
// contact_tolerance, facing its way and later (on top by the coincident-face rule: a rug laid on
// a floor). Only a surface that is one outline cuts (its triangles of one material and plane fill
// their convex hull, or it is one triangle). No strips: the gap is dark, not bright. The pieces
// over the surface are Triangle::in_gap as well. Faces look at the surfaces near them through a
// grid; past kMaxGapCutPairs looked at, the rest are not cut for surfaces, and a scene of more
// than kMaxSurfaceCutFaces triangles is cut for its emitters only (grouping every triangle into
// surfaces would take minutes and gigabytes).
inline constexpr double kGapCut = 0.25;
inline constexpr double kGapCutSurface = 1.0 / 8.0;
inline constexpr double kGapStripsFrom = 1.0 / 256.0;
inline constexpr std::array<double, 1> kGapStripsOut = {1.0};
inline constexpr std::array<double, 2> kGapStripsIn = {0.5, 2.0};
inline constexpr std::array<double, 1> kGapStripsEmitter = {2.0};
// No strip cut leaves a piece smaller than kGapStripLeast x g x the emitter's extent (a strip is
// about g wide and as long as the emitter): a patch that few lines cross has an estimate of a few
// large values, and a chain passes each on to the patches its lines reach, so the bits that a
// face's own edges cut off a strip's corner stay with the piece beside them.
inline constexpr double kGapStripLeast = 1.0 / 8.0;
inline constexpr double kMaxGapCutPairs = 1e8;
inline constexpr std::size_t kMaxSurfaceCutFaces = std::size_t{1} << 20;
void cut_along_gaps(Scene& scene);
// Marks the faces no light reaches (Triangle::unlit): no random walk from a face's front
// (scene/light_walks.h) meets or sees an emitter's front: the outer faces of a building's walls
// and slabs that face away from every light. Emitting faces are never marked. The mesher leaves
// them whole; a face marked wrongly (light that the walks missed) is only meshed coarsely.
// Scenes of more than kMaxMarkedFaces (scene/light_walks.h) triangles are left unmarked.
void mark_unlit_faces(Scene& scene);

// The built-in scenes. `furnace`: a closed cube (side 1, inward normals), every face E = 1,
// rho = 0.5, so B = 2 exactly everywhere.
// True for the name of a built-in scene (load_scene's names that are no file).
bool is_builtin_scene(const std::string& name);
Scene builtin_cornell();
Scene builtin_furnace();
// `bright-room`: a closed room with rho 0.85-0.9 and one ceiling light (scenes/bright_room.obj).
// `three-lights`: an open-front room with three lights of 1, 0.1, 0.01 m^2 (scenes/three_lights.obj).
Scene builtin_bright_room();
Scene builtin_three_lights();
std::vector<std::string> builtin_scene_names();

// A camera that frames the scene's bounding box from outside (along +Z), for scenes that carry
// none (scene/check.h check_scene picks one that sees the most).
Camera default_camera(const Scene& scene);

// "eye X Y Z look X Y Z up X Y Z fov DEG" (the OBJ comment `# sirad camera ...` and --camera):
// every part once, finite numbers, fov in (0, 180), a view direction and an up not along it.
// Throws sirad::Error saying what is wrong (without a place: the caller adds it).
Camera parse_camera(std::string_view spec);
// The same form, for messages and the EXR (sirad.camera); parse_camera reads it back.
std::string camera_spec(const Camera& camera);

}  // namespace sirad
