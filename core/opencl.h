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

// "clEnqueueNDRangeKernel: CL_OUT_OF_RESOURCES (-5)".
std::string describe_cl_error(const cl::Error& e);

}  // namespace sirad
