// sirad: images of a solution: the Image type every writer and renderer shares, the
// corner values that shade a patch mesh smoothly, and the rasteriser that draws the patches
// from a camera (render/render_view.cpp). The final gather (render/gather.h) makes the images a
// path tracer would; io/write.h writes them.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/camera.h"
#include "scene/mesh.h"

namespace sirad {

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
// it); patches in one plane blend only if they see each other (a wall standing on a floor
// between them, a zero-thickness one too, keeps each room's light its own: the final gather's
// lookups, the outputs' corners). Result: 3 values per patch.
std::vector<std::array<glm::vec3, 3>> corner_radiosity(const PatchMesh& mesh,
                                                       const std::vector<glm::vec3>& radiosity);

// Renders the mesh from `camera` with a z-buffer; pixels that see no front face show the
// background (back faces are culled, as the solver treats them).
Image render_view(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity,
                  const Camera& camera, int width, int height, Shading shading);

// render_view with s x s samples per pixel, averaged (a box filter over each pixel's square, in
// linear radiance): the same framing, without jagged edges. s = 1 is render_view.
Image render_view_antialiased(const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, const Camera& camera,
                              int width, int height, Shading shading, int samples_per_side);

}  // namespace sirad
