// sirad: text embedded into the binary at build time (kernels/*.cl, scenes/*).
#pragma once
#include <string>
#include <string_view>

namespace sirad {
// The embedded file at `name` (path relative to the source root, e.g. "kernels/bundle.cl").
// Throws std::out_of_range for an unknown name.
std::string_view resource(std::string_view name);
}  // namespace sirad
