// sirad: the bundle engine on an OpenCL device (kernels/bundle.cl).
#pragma once
#include <memory>
#include <string>

#include "core/bundle.h"
#include "core/opencl.h"

namespace sirad {

struct ClEngineOptions {
  std::string device;  // see select_device; empty: SIRAD_DEVICE or the first PoCL CPU device
  int bands = 0;       // work-items (bands of grid rows) of the transfer pass; 0: chosen for the device
  int block_lines = 0; // lines per block of rows in the transfer pass (rows = this / grid, at
                       // least 1, at most a band); 0: SIRAD_BLOCK_LINES or 8192
  uint64_t row_capacity = 0;  // first scratch size for one block's crossings (it grows on demand);
                              // 0: a few times an even share of capacity_bound
  uint64_t list_capacity = 0; // first scratch size for the patches reaching one band (grows);
                              // 0: a few times an even share of the patches
};

// Runs bundles on one OpenCL device. Throws sirad::Error for a missing device or platform,
// a failed build, or an OpenCL failure.
std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& options = {});

}  // namespace sirad
