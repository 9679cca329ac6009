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
//   SIRAD_PATH          path         (band or wide)
//   SIRAD_BANDS         bands
//   SIRAD_BLOCK_LINES   block_lines
//   SIRAD_PROJECT8      project8     (0 or 1)
//   SIRAD_PROFILE       profile      (set: per-kernel times on stderr)
//   SIRAD_CL_OPTIONS    extra kernel build flags (kernel_build_options reads it: experiments)
// The two ways of running a bundle's transfer (DESIGN.md section 2, "Two transfer paths"):
//   band  one work-item per band of grid rows, each written CPU-style (kernels/bundle.cl);
//   wide  one work-item per patch, per (patch, row) span or per line, with device scans
//         between the passes (kernels/bundle_wide.cl): for devices with many lanes.
// Both give the C++ reference's crossings and hits; wide adds each patch's crossings in the
// reference's order (the same bits), band per band of rows.
enum class TransferPath { band, wide };
TransferPath parse_transfer_path(const std::string& name);  // "band" | "wide"; throws sirad::Error
const char* to_string(TransferPath path);

struct ClEngineOptions {
  std::string device;  // see select_device; empty: SIRAD_DEVICE or the first PoCL CPU device
  std::optional<TransferPath> path;  // default: band on a CPU device, wide on any other
  int bands = 0;       // work-items (bands of grid rows) of the transfer pass; 0: chosen for the device
  int block_lines = 0; // lines per block of rows in the transfer pass (rows = this / grid, at
                       // least 1, at most a band); 0: 8192
  std::optional<bool> project8;  // eight patches per step in float8 lanes (default: on a CPU)
  bool profile = false;          // time each kernel (OpenCL profiling) and print the times
  uint64_t row_capacity = 0;  // first scratch size for one block's crossings (it grows on demand);
                              // 0: a few times an even share of capacity_bound
  uint64_t list_capacity = 0; // first scratch size for the patches reaching one band (grows);
                              // 0: a few times an even share of the patches
  uint64_t span_capacity = 0;      // wide path: first room for (patch, row) spans (grows); 0: a bound
  uint64_t crossing_capacity = 0;  // wide path: first room for crossings (grows); 0: a bound
};

// `options` with the environment's overrides of the fields left unset (see ClEngineOptions).
ClEngineOptions with_environment(ClEngineOptions options);

// Runs bundles on one OpenCL device, tuned by with_environment(options). Throws sirad::Error for a missing device or platform,
// a failed build, or an OpenCL failure.
std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& options = {});

}  // namespace sirad
