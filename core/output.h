// sirad: the solver's outputs (DESIGN.md section 4): an EXR seen from the scene camera
// (linear float RGB, Gouraud-shaded from vertex radiosities, header attributes with the run's
// settings), a tone-mapped sRGB PNG of the same view and a binary PLY of the patches.
// Every file is written atomically: to a temporary name beside it, then renamed.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <glm/vec3.hpp>

#include "core/mesh.h"

namespace sirad {

// A run setting recorded in the EXR header, e.g. {"sirad.bundles", int64_t{1024}}.
using AttributeValue = std::variant<int64_t, double, std::string>;
using Attributes = std::vector<std::pair<std::string, AttributeValue>>;

// The largest image side any writer, the final gather and the image phase's tiles take.
inline constexpr int kMaxImageSide = 16384;
// The most pixels of an image (8K UHD, 7680 x 4320, is 33.2 million): its final gather's three
// passes then take 1.2 GB, known when the flags are read, not after a solve.
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 25;

struct Image {
  int width = 0, height = 0;
  std::vector<glm::vec3> pixels;  // row-major, top row first
  glm::vec3& at(int x, int y) { return pixels[static_cast<std::size_t>(y) * width + x]; }
  const glm::vec3& at(int x, int y) const { return pixels[static_cast<std::size_t>(y) * width + x]; }
};

enum class Shading { gouraud, flat };

// Per-patch-corner radiosity for Gouraud shading: the area-weighted mean of the patches that
// share the welded vertex, restricted to those with the same material and a normal within
// 30 degrees (so creases and material borders stay sharp), and on the same side of an emitter's
// outline (PatchMesh::in_gap: the light trapped over a lamp never blends into the ceiling beside
// it). Result: 3 values per patch.
std::vector<std::array<glm::vec3, 3>> corner_radiosity(const PatchMesh& mesh,
                                                       const std::vector<glm::vec3>& radiosity);

// The vertices of `patches` (in that order) for a format with one value per vertex: one per
// welded position and corner value (corners with one value share one: a smooth surface of one
// material; creases and material borders split). `vertex` and `value` get each new vertex's
// welded index and value, in order of first use; returns 3 vertex indices per patch.
std::vector<uint32_t> split_corners(const PatchMesh& mesh, const std::vector<std::array<glm::vec3, 3>>& corners,
                                    const std::vector<uint32_t>& patches, std::vector<uint32_t>& vertex,
                                    std::vector<glm::vec3>& value);

// Renders the mesh from `camera` with a z-buffer; pixels that see no front face show the
// background (back faces are culled, as the solver treats them).
Image render_view(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity,
                  const Camera& camera, int width, int height, Shading shading);

// render_view with s x s samples per pixel, averaged (a box filter over each pixel's square, in
// linear radiance): the same framing, without jagged edges. s = 1 is render_view.
Image render_view_antialiased(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, const Camera& camera,
                              int width, int height, Shading shading, int samples_per_side);

void write_exr(const std::string& path, const Image& image, const Attributes& attributes);
// Several images of one size in one EXR, as compositors read passes: the layer named "" as R,
// G, B, each other as NAME.R, NAME.G, NAME.B.
void write_exr_layers(const std::string& path, const std::vector<std::pair<std::string, const Image*>>& layers,
                      const Attributes& attributes);
// Tone map: pixel * 2^exposure, clamped to [0, 1], sRGB-encoded, 8 bits.
void write_png(const std::string& path, const Image& image, float exposure = 0.0f);
// The PLY of DESIGN.md section 4: one face per patch in patch order with its radiosity,
// reflectance and emission (and sirad_in_gap, 0 or 1, where some patch lies over an emitter:
// PatchMesh::in_gap); a vertex per welded position and corner value (corner_radiosity:
// shared within one smooth surface of one material, split at creases and material borders)
// with red green blue = the tone map of the PNG (times 2^exposure, clamped, sRGB bytes), the
// vertex colours Blender's PLY importer shows.
void write_ply(const std::string& path, const PatchMesh& mesh,
               const std::vector<glm::vec3>& radiosity, float exposure = 0.0f);

}  // namespace sirad
