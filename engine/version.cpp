// sirad: the --version text of every binary.
#include "engine/version.h"

#include <map>

#include <fmt/format.h>

#include "engine/opencl.h"
#include "util/error.h"

namespace sirad {

const char* const kVersion = SIRAD_VERSION;

std::string version_text(const std::string& program) {
  std::string out = fmt::format("{} {} (git {})\n", program, kVersion, kGitCommit);
  try {
    std::map<int, std::vector<DeviceInfo>> platforms;
    for (DeviceInfo& d : list_devices()) platforms[d.platform].push_back(std::move(d));
    if (platforms.empty()) out += "OpenCL: no device\n";
    for (const auto& [index, devices] : platforms) {
      out += fmt::format("OpenCL platform {}: {}:", index, devices.front().platform_name);
      for (const DeviceInfo& d : devices) out += fmt::format(" [{}:{}] {} ({})", d.platform, d.device, d.device_name, d.version);
      out += "\n";
    }
  } catch (const std::exception& e) {
    out += fmt::format("OpenCL: {}\n", e.what());
  }
  out.pop_back();  // the last line's newline: the caller ends the text
  return out;
}

}  // namespace sirad
