// sirad: OpenCL device choice, error text and the per-(context, device) program cache.
#include "engine/opencl.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <map>
#include <mutex>
#include <tuple>

#include <fmt/format.h>

#include "util/error.h"
#include "util/resources.h"

namespace sirad {

namespace {

const char* cl_error_name(cl_int code) {
  switch (code) {
    case CL_DEVICE_NOT_FOUND: return "CL_DEVICE_NOT_FOUND";
    case CL_DEVICE_NOT_AVAILABLE: return "CL_DEVICE_NOT_AVAILABLE";
    case CL_COMPILER_NOT_AVAILABLE: return "CL_COMPILER_NOT_AVAILABLE";
    case CL_MEM_OBJECT_ALLOCATION_FAILURE: return "CL_MEM_OBJECT_ALLOCATION_FAILURE";
    case CL_OUT_OF_RESOURCES: return "CL_OUT_OF_RESOURCES";
    case CL_OUT_OF_HOST_MEMORY: return "CL_OUT_OF_HOST_MEMORY";
    case CL_BUILD_PROGRAM_FAILURE: return "CL_BUILD_PROGRAM_FAILURE";
    case CL_INVALID_VALUE: return "CL_INVALID_VALUE";
    case CL_INVALID_PLATFORM: return "CL_INVALID_PLATFORM";
    case CL_INVALID_DEVICE: return "CL_INVALID_DEVICE";
    case CL_INVALID_BUFFER_SIZE: return "CL_INVALID_BUFFER_SIZE";
    case CL_INVALID_KERNEL_ARGS: return "CL_INVALID_KERNEL_ARGS";
    case CL_INVALID_WORK_GROUP_SIZE: return "CL_INVALID_WORK_GROUP_SIZE";
    case CL_INVALID_WORK_ITEM_SIZE: return "CL_INVALID_WORK_ITEM_SIZE";
    case CL_INVALID_GLOBAL_WORK_SIZE: return "CL_INVALID_GLOBAL_WORK_SIZE";
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR";
    default: return "OpenCL error";
  }
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\0' || std::isspace(static_cast<unsigned char>(s.back())))) s.pop_back();
  return s;
}

std::vector<cl::Platform> platforms() {
  std::vector<cl::Platform> list;
  try {
    cl::Platform::get(&list);
  } catch (const cl::Error& e) {
    if (e.err() != -1001) throw Error("OpenCL: " + describe_cl_error(e));
  }
  if (list.empty())
    fail("no OpenCL platform found (install an ICD such as pocl-opencl-icd; check with `clinfo`)");
  return list;
}

std::vector<cl::Device> devices_of(const cl::Platform& p) {
  std::vector<cl::Device> list;
  try {
    p.getDevices(CL_DEVICE_TYPE_ALL, &list);
  } catch (const cl::Error&) {
    // A platform without devices lists none.
  }
  return list;
}

}  // namespace

std::string describe_cl_error(const cl::Error& e) {
  return fmt::format("{}: {} ({})", e.what(), cl_error_name(e.err()), e.err());
}

DeviceInfo describe_device(const cl::Device& device) {
  DeviceInfo info;
  cl::Platform platform(device.getInfo<CL_DEVICE_PLATFORM>());
  info.platform_name = trim(platform.getInfo<CL_PLATFORM_NAME>());
  info.device_name = trim(device.getInfo<CL_DEVICE_NAME>());
  info.version = trim(device.getInfo<CL_DEVICE_VERSION>());
  info.is_cpu = (device.getInfo<CL_DEVICE_TYPE>() & CL_DEVICE_TYPE_CPU) != 0;
  info.compute_units = device.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  return info;
}

namespace {
// Every device of every platform, with its indices. Serialised: an ICD loader and PoCL are
// not safe to initialise from several threads at once (the embedded cluster's nodes do).
std::vector<std::pair<DeviceInfo, cl::Device>> enumerate_devices() {
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  std::vector<std::pair<DeviceInfo, cl::Device>> all;
  auto ps = platforms();
  for (std::size_t p = 0; p < ps.size(); ++p) {
    auto ds = devices_of(ps[p]);
    for (std::size_t d = 0; d < ds.size(); ++d) {
      DeviceInfo info = describe_device(ds[d]);
      info.platform = static_cast<int>(p);
      info.device = static_cast<int>(d);
      all.emplace_back(info, ds[d]);
    }
  }
  return all;
}
}  // namespace

std::vector<DeviceInfo> list_devices() {
  std::vector<DeviceInfo> out;
  for (auto& [info, dev] : enumerate_devices()) out.push_back(info);
  return out;
}

cl::Device select_device(const std::string& requested) {
  std::string spec = requested;
  if (spec.empty())
    if (const char* env = std::getenv("SIRAD_DEVICE")) spec = env;
  auto all = enumerate_devices();
  if (all.empty()) fail("no OpenCL device found (check with `clinfo`)");

  auto listing = [&] {
    std::string s;
    for (auto& [info, dev] : all)
      s += fmt::format("{}{}:{} {} / {}", s.empty() ? "" : "; ", info.platform, info.device,
                       info.platform_name, info.device_name);
    return s;
  };

  if (spec.empty()) {
    for (auto& [info, dev] : all)
      if (info.is_cpu && lower(info.platform_name).find("portable computing language") != std::string::npos)
        return dev;
    return all.front().second;
  }
  // "P:D": platform and device index.
  int p = -1, d = -1;
  char tail = 0;
  if (std::sscanf(spec.c_str(), "%d:%d%c", &p, &d, &tail) == 2) {
    for (auto& [info, dev] : all)
      if (info.platform == p && info.device == d) return dev;
    fail("OpenCL device {}: no such platform:device (there are: {})", spec, listing());
  }
  for (auto& [info, dev] : all)
    if (lower(info.platform_name + " / " + info.device_name).find(lower(spec)) != std::string::npos)
      return dev;
  fail("OpenCL device '{}' matches none (there are: {})", spec, listing());
}

cl::Program build_program(const cl::Context& context, const cl::Device& device,
                          const std::vector<std::string>& resource_names, const std::string& options) {
  using Key = std::tuple<cl_context, cl_device_id, std::vector<std::string>, std::string>;
  static std::mutex mutex;
  static std::map<Key, cl::Program> cache;
  std::lock_guard lock(mutex);
  Key key{context(), device(), resource_names, options};
  if (auto it = cache.find(key); it != cache.end()) return it->second;

  std::string source;
  for (const auto& name : resource_names) {
    source += fmt::format("#line 1 \"{}\"\n", name);
    source += resource(name);
    source += "\n";
  }
  cl::Program program(context, source);
  try {
    program.build(std::vector<cl::Device>{device}, options.c_str());
  } catch (const cl::Error&) {
    std::string log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(device);
    for (char& c : log)
      if (c == '\n') c = ' ';
    fail("OpenCL build of {} failed: {}", resource_names.back(), trim(log));
  }
  cache.emplace(key, program);
  return program;
}

std::string kernel_build_options(const cl::Device& device) {
  std::string build = "-cl-std=CL1.2";
  if (device.getInfo<CL_DEVICE_SINGLE_FP_CONFIG>() & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT)
    build += " -cl-fp32-correctly-rounded-divide-sqrt";
  if (const char* extra = std::getenv("SIRAD_CL_OPTIONS")) build += std::string(" ") + extra;
  return build;
}

WorkRuns work_runs(const DeviceInfo& info, std::size_t count) {
  WorkRuns r;
  r.items = info.is_cpu ? std::min<std::size_t>(std::max<std::size_t>(count, 1), 16 * info.compute_units)
                        : std::max<std::size_t>(count, 1);
  r.per_item = static_cast<cl_uint>((count + r.items - 1) / r.items);
  return r;
}

}  // namespace sirad
