// sirad: the files of DESIGN.md section 4 that hold images and patches: EXR (linear float RGB,
// one image or several passes, header attributes with the run's settings), a tone-mapped sRGB
// PNG, and a binary PLY of the patches with their radiosity. The images come from render/;
// io/results.h writes a run's outputs with these, io/write_gltf.h the glTF.
// Every file is written atomically: to a temporary name beside it, then renamed.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <glm/vec3.hpp>

#include "render/image.h"
#include "scene/mesh.h"

namespace sirad {

// A run setting recorded in the EXR header, e.g. {"sirad.bundles", int64_t{1024}}.
using AttributeValue = std::variant<int64_t, double, std::string>;
using Attributes = std::vector<std::pair<std::string, AttributeValue>>;

// The vertices of `patches` (in that order) for a format with one value per vertex: one per
// welded position and corner value (corners with one value share one: a smooth surface of one
// material; creases and material borders split). `vertex` and `value` get each new vertex's
// welded index and value, in order of first use; returns 3 vertex indices per patch.
std::vector<uint32_t> split_corners(const PatchMesh& mesh, const std::vector<std::array<glm::vec3, 3>>& corners,
                                    const std::vector<uint32_t>& patches, std::vector<uint32_t>& vertex,
                                    std::vector<glm::vec3>& value);

void write_exr(const std::string& path, const Image& image, const Attributes& attributes);
// The channels' type: 32-bit float, or half (16-bit: 3 significant digits, up to kHalfMax;
// larger values are refused), as engines load lightmaps.
enum class ExrPixel { full, half };
inline constexpr float kHalfMax = 65504.0f;
// Several images of one size in one EXR, as compositors read passes: the layer named "" as R,
// G, B, each other as NAME.R, NAME.G, NAME.B.
void write_exr_layers(const std::string& path, const std::vector<std::pair<std::string, const Image*>>& layers,
                      const Attributes& attributes, ExrPixel pixel = ExrPixel::full);
// Tone map: pixel * 2^exposure, clamped to [0, 1], sRGB-encoded, 8 bits.
void write_png(const std::string& path, const Image& image, float exposure = 0.0f);
// The same PNG as bytes (to embed in a glTF); `what` names it in errors.
std::vector<unsigned char> png_bytes(const std::string& what, const Image& image, float exposure = 0.0f);
// The PLY of DESIGN.md section 4: one face per patch in patch order with its radiosity,
// reflectance and emission (and sirad_in_gap, 0 or 1, where some patch lies over an emitter:
// PatchMesh::in_gap); a vertex per welded position and corner value (corner_radiosity:
// shared within one smooth surface of one material, split at creases and material borders)
// with red green blue = the tone map of the PNG (times 2^exposure, clamped, sRGB bytes), the
// vertex colours Blender's PLY importer shows. `error_estimate` (the run's, >= 0) goes into the
// comment `sirad error estimate E`: a warm start from the file counts it (solver/warm_start.h).
void write_ply(const std::string& path, const PatchMesh& mesh,
               const std::vector<glm::vec3>& radiosity, float exposure = 0.0f, double error_estimate = -1.0);

}  // namespace sirad
