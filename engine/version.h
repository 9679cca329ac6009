// sirad: what every binary says to --version: sirad's version, the git commit it was built
// from (cmake/version.cmake) and the OpenCL platforms this machine offers.
#pragma once
#include <string>

namespace sirad {

extern const char* const kVersion;    // the project's version (CMakeLists.txt)
extern const char* const kGitCommit;  // 12 hex digits, "-dirty" for uncommitted changes, or "unknown"

// "PROGRAM VERSION (git COMMIT)" and a line per OpenCL platform with its devices, or one
// saying there is none, without a newline at the end. Never throws.
std::string version_text(const std::string& program);

}  // namespace sirad
