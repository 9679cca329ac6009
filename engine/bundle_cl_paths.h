// sirad: the OpenCL bundle engine's two transfer paths, for engine/bundle_cl.cpp's make_cl_engine
// (which chooses one per device); not for other callers.
#pragma once
#include <memory>

#include "engine/bundle_cl.h"

namespace sirad {

// The mesh as both paths' kernels read it: vertices relative to the bounding-sphere centre
// (centred_vertices) and patches as uint4, in read-only device buffers.
struct MeshBuffers {
  cl::Buffer vertices, patches;
};
MeshBuffers upload_mesh(const cl::Context& context, const PatchMesh& mesh);

// The wide path (kernels/bundle_wide.cl): one work-item per patch, per (patch, row) span or per
// line; for devices with many lanes.
std::unique_ptr<BundleEngine> make_wide_engine(const PatchMesh& mesh, const ClEngineOptions& options);

}  // namespace sirad
