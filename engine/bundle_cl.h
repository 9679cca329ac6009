// sirad: the bundle engine on an OpenCL device (kernels/bundle.cl).
#pragma once
#include <memory>
#include <optional>
#include <string>

#include "engine/bundle.h"
#include "engine/opencl.h"

namespace sirad {

// The engine's tuning. Fields left at 0 (or unset) take the environment's override, read in one
// place (make_cl_engine: with_environment), else the engine's choice for the device:
//   SIRAD_DEVICE        device       (select_device reads it)
//   SIRAD_BANDS         bands
//   SIRAD_BLOCK_LINES   block_lines
//   SIRAD_PROJECT8      project8     (0 or 1)
//   SIRAD_PROFILE       profile      (set: per-kernel times on stderr)
//   SIRAD_CL_OPTIONS    extra kernel build flags (kernel_build_options reads it: experiments)
struct ClEngineOptions {
  std::string device;  // see select_device; empty: SIRAD_DEVICE or the first PoCL CPU device
  int bands = 0;       // work-items (bands of grid rows) of the transfer pass; 0: chosen for the device
  int block_lines = 0; // lines per block of rows in the transfer pass (rows = this / grid, at
                       // least 1, at most a band); 0: 8192
  std::optional<bool> project8;  // eight patches per step in float8 lanes (default: on a CPU)
  bool profile = false;          // time each kernel (OpenCL profiling) and print the times
  uint64_t row_capacity = 0;  // first scratch size for one block's crossings (it grows on demand);
                              // 0: a few times an even share of capacity_bound
  uint64_t list_capacity = 0; // first scratch size for the patches reaching one band (grows);
                              // 0: a few times an even share of the patches
};

// `options` with the environment's overrides of the fields left unset (see ClEngineOptions).
ClEngineOptions with_environment(ClEngineOptions options);

// Runs bundles on one OpenCL device, tuned by with_environment(options). Throws sirad::Error for a missing device or platform,
// a failed build, or an OpenCL failure.
std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& options = {});

}  // namespace sirad
