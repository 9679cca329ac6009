// sirad: the OpenCL host side shared by every engine: choosing a device (flag, environment,
// index or name), turning OpenCL errors into one-line sirad errors, and building programs
// once per (context, device, source, options).
#pragma once
#include <string>
#include <vector>

#include <CL/opencl.hpp>

namespace sirad {

struct DeviceInfo {
  int platform = 0, device = 0;  // indices as `sirad devices` lists them
  std::string platform_name, device_name, version;
  bool is_cpu = false;
  unsigned compute_units = 1;
};

// Every device of every platform. Throws sirad::Error if there is no OpenCL platform.
std::vector<DeviceInfo> list_devices();

// Chooses a device: `spec` empty (then the SIRAD_DEVICE environment variable, then the first
// PoCL CPU device, then the first device of any platform), "P:D" (platform and device index),
// or a case-insensitive substring of "platform / device" names. Throws sirad::Error naming the
// spec and the devices there are when nothing matches.
cl::Device select_device(const std::string& spec);
DeviceInfo describe_device(const cl::Device& device);

// A program from embedded sources, built once per (context, device, sources, options) and
// cached for the life of the process; a failed build throws with the build log.
cl::Program build_program(const cl::Context& context, const cl::Device& device,
                          const std::vector<std::string>& resource_names,
                          const std::string& options);

// The build options of every sirad program on `device`: OpenCL C 1.2, correctly rounded divide
// and sqrt where the device offers them (the kernels then round like the host), and for
// experiments the SIRAD_CL_OPTIONS environment variable appended.
std::string kernel_build_options(const cl::Device& device);

// Runs of `count` items (patches, vertices) per work-item: on a CPU whole runs, 16 per compute
// unit (no divergent lanes, enough to balance the threads); elsewhere one item per work-item.
struct WorkRuns {
  std::size_t items = 1;  // work-items
  cl_uint per_item = 1;   // consecutive items each takes
};
WorkRuns work_runs(const DeviceInfo& info, std::size_t count);

// Sets `kernel`'s arguments 0, 1, 2, ... to `args`, in order.
template <class... Args>
void set_args(cl::Kernel& kernel, const Args&... args) {
  cl_uint index = 0;
  (kernel.setArg(index++, args), ...);
}

// "clEnqueueNDRangeKernel: CL_OUT_OF_RESOURCES (-5)".
std::string describe_cl_error(const cl::Error& e);

}  // namespace sirad
