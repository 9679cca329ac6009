// sirad: a lightmap atlas of a scene (issue 38): its input faces grouped into charts, each chart
// laid flat on its plane and packed, with gutters, into one texture of texels of a set size.
//   - A chart is a set of triangles of one object that share edges and lie within 2 degrees of
//     its first face's plane (the faces of a wall, a door cut out of it by a Boolean included, a
//     quad not quite in one plane too): no seam crosses a flat surface, so filtering and the
//     texels' samples see one continuous surface.
//   - Each chart is projected onto its plane and turned to its least bounding rectangle (the
//     rotating calipers over its convex hull: a wall at 30 degrees costs no more texels than one
//     on the axes); a texel is texel_size on a side in the scene's units, so every surface has
//     one density.
//   - The charts, each with `gutter` empty texels around it, are packed in shelves (tallest
//     first) into an atlas about as wide as it is tall; a filter reaching `gutter` texels beyond
//     a chart never reaches another.
// A scene whose file has its own lightmap UV set (glTF TEXCOORD_1: Scene::uv_maps) is laid out as
// the file says, unless told otherwise (AtlasOptions::file_layout):
//   - The file's unit UV square becomes the atlas's top-left file_width x file_height texels; its
//     charts are the faces joined by corners at the same place with the same UV (a UV island,
//     curved or not), and a texel is the chart's that holds its centre (as bakers rasterise),
//     else the one that covers most of it (16 points tried: a texel on an island's rim), or,
//     within `gutter` texels of one, the nearest chart's (ring by ring, lowest chart first).
//   - The faces the file gives no place (back sides of two-sided faces, which share their
//     front's UV; faces without TEXCOORD_1 or with no area or corners outside [0, 1] in it) get
//     sirad's own charts, packed in shelves below the square at the file's mean texel size. With
//     none, the layout is the file's exactly.
//   - Its size is the one the file names (Scene::lightmap_size: a glb sirad baked) unless a
//     texel size is given; else the texel size's (the file's UV area against its faces' area),
//     in the named size's proportions or square, whole blocks of 4.
// Texel (i, j) covers [i, i + 1) x [j, j + 1) in texel units, rows top first; a triangle
// corner's UV is its texel position over the atlas size, as glTF's TEXCOORD_1 takes it (u right,
// v down). Plain geometry: no rays, no radiosity.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad {

struct AtlasOptions {
  // A texel's side in the scene's units; 0: the size that covers the scene's surface with about
  // texel_budget texels.
  double texel_size = 0;
  uint64_t texel_budget = uint64_t{1} << 20;
  int gutter = 2;  // empty texels around each chart, 0..64
  // The atlas's largest side: a texel_size that needs more is refused; from a budget, the texel
  // size grows until the atlas fits. 16..16384.
  int max_side = 8192;
  // The file's own lightmap UV set where the scene has one (above); false: sirad's charts only.
  bool file_layout = true;
};

inline constexpr uint32_t kNoChart = 0xffffffffu;

struct Chart {
  std::vector<uint32_t> triangles;  // the scene's, in their order
  // Its plane's frame: point p lies at texel ((p - origin) . u, (p - origin) . v) / texel_size
  // of the chart's rectangle, inside its gutter.
  glm::dvec3 origin{0.0}, u{0.0}, v{0.0}, normal{0.0};
  // Its rectangle in the atlas, in texels, gutters included: [x, x + width) x [y, y + height).
  // In the file's layout, the bounds of its texels (Atlas::owner), which other charts' may share.
  int x = 0, y = 0, width = 0, height = 0;
  // A texel's side on its surface, in the scene's units (the atlas's; in the file's layout, the
  // chart's mean), and whether its faces lie in one plane (sirad's charts; origin, u and v are
  // then its frame, else zero and `normal` its faces' mean).
  double texel = 0;
  bool flat = true;
};

// An edge where two faces are one surface (one material, within 2 degrees, both in a gap or
// neither, not along a contact segment: no wall stands there) but have different texels: two
// charts meet there, or one chart twice (the file's layout). Its two ends in each face's UV,
// the same points in the same order.
struct Seam {
  uint32_t a = 0, b = 0;  // the faces
  std::array<glm::vec2, 2> uv_a{}, uv_b{};
};

struct Atlas {
  int width = 0, height = 0;  // texels
  double texel_size = 0;
  int gutter = 0;
  std::vector<Chart> charts;
  std::vector<uint32_t> chart_of;               // per scene triangle
  std::vector<std::array<glm::vec2, 3>> uv;     // per scene triangle, its corners' UV in [0, 1]
  // Per texel, rows top first: the chart whose texel it is (its faces' or its gutter's), or kNoChart.
  std::vector<uint32_t> owner;
  // The file's layout: its UV square's size in texels (0: sirad's own layout), and the texels
  // more than one chart covers a quarter of (overlapping islands in the file's UV set).
  int file_width = 0, file_height = 0;
  std::size_t shared_texels = 0;
  std::vector<Seam> seams;
  // The texels of the charts' faces (in sirad's layout their rectangles, gutters left out; in
  // the file's, those a face covers most of), and their share of the atlas.
  std::size_t face_texels = 0;
  double fill() const;
};

// `scene` with each face cut along the segments where another face stands on it or crosses it
// (scene/contacts.h contact_segments: the foot of a wall on a floor slab that runs on under it,
// an inner wall against an outer one), each convex piece fanned into triangles that keep the
// face's material, object, line and flags. With make_atlas, which joins no faces across such a
// segment, no chart spans the foot of a wall: the floors of two rooms either side of a
// zero-thickness wall get texels of their own, and no texel (nor its filtering) mixes them.
// Pieces under a solid are kept (their texels are never seen; the bake leaves such samples
// out). At most kMaxPiecesPerFace pieces a face (cuts past that are not made).
inline constexpr std::size_t kMaxPiecesPerFace = 64;
Scene cut_at_contacts(const Scene& scene);

// The atlas of `scene` (every triangle, unlit ones included: they are surfaces a viewer sees),
// in the file's layout where it has one and options.file_layout.
// Faces are not joined across an edge that lies along a contact segment (cut_at_contacts).
// Throws sirad::Error for options out of range, a texel size that needs an atlas wider or
// taller than max_side (naming the size it would take), or a file's UV set whose faces' bounds
// hold more than 8 times the square's texels and 16 a face (islands laid over each other).
Atlas make_atlas(const Scene& scene, const AtlasOptions& options);

}  // namespace sirad
