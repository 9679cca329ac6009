// sirad: the bundle engine on an OpenCL device (kernels/bundle.cl).
#pragma once
#include <memory>
#include <string>

#include "core/bundle.h"
#include "core/opencl.h"

namespace sirad {

struct ClEngineOptions {
  std::string device;  // see select_device; empty: SIRAD_DEVICE or the first PoCL CPU device
  int bands = 0;       // work-items of the count/fill passes; 0: chosen for the device
};

// Runs bundles on one OpenCL device. Throws sirad::Error for a missing device or platform,
// a failed build, or an OpenCL failure.
std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& options = {});

}  // namespace sirad
