// sirad: what the scene readers share (OBJ in scene/scene.cpp, glTF in scene/gltf.cpp, PLY
// in scene/ply.cpp): their limits, the one way they read a file, and how text from a file
// enters a message or an output. Internal to the readers.
#pragma once
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "util/limits.h"

namespace sirad::import {

inline constexpr std::size_t kMaxVertices = std::size_t{1} << 26;
// A scene's triangles, the twins of two-sided materials and the pieces cut along emitters
// included: 52 bytes each, 870 MB at the bound, whatever a small file names (a glTF mesh used by
// many nodes is counted once per node before any is made).
inline constexpr std::size_t kMaxTriangles = std::size_t{1} << 24;
inline constexpr float kDefaultReflectance = 0.8f;  // a face without a material

// The whole file: a regular file of at most 2 GiB, or one error naming `label` (no such file,
// a directory, a device or FIFO, too large, unreadable).
std::string read_file(const std::filesystem::path& path, const std::string& label);

// Text from a file for a one-line message: at most 40 bytes, non-printables (and non-ASCII) as
// '?', "..." when cut.
std::string printable(std::string_view s);
// A name from a file as it may be kept (object and material names): at most `max` bytes, control
// bytes as '?' (UTF-8 stays).
std::string without_controls(std::string_view s, std::size_t max);

// The sRGB transfer function's inverse (an 8-bit colour from a file to linear reflectance).
double srgb_to_linear(double c);

}  // namespace sirad::import
