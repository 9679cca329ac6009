// sirad: the OpenCL bundle engine: buffers, launches and read-back for one bundle.
#include "core/bundle_cl.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "core/error.h"

namespace sirad {

namespace {

constexpr std::size_t kPatchGroup = 64;  // local size of the per-patch kernels (fixed: PoCL
                                         // compiles once per local size)

std::size_t round_up(std::size_t n, std::size_t m) { return (n + m - 1) / m * m; }

class ClEngine final : public BundleEngine {
 public:
  ClEngine(const PatchMesh& mesh, const ClEngineOptions& options) : n_(mesh.size()) {
    device_ = select_device(options.device);
    info_ = describe_device(device_);
    context_ = cl::Context(device_);
    profile_ = std::getenv("SIRAD_PROFILE") != nullptr;
    queue_ = cl::CommandQueue(context_, device_, profile_ ? CL_QUEUE_PROFILING_ENABLE : 0);
    std::string build = "-cl-std=CL1.2";
    cl_device_fp_config fp = device_.getInfo<CL_DEVICE_SINGLE_FP_CONFIG>();
    if (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) build += " -cl-fp32-correctly-rounded-divide-sqrt";
    cl::Program program = build_program(context_, device_, {"kernels/bundle_types.h", "kernels/bundle.cl"}, build);
    project_ = cl::Kernel(program, "project_patches");
    count_ = cl::Kernel(program, "count_crossings");
    fill_ = cl::Kernel(program, "fill_crossings");
    gather_ = cl::Kernel(program, "gather");

    bands_ = options.bands;
    if (bands_ <= 0)
      if (const char* env = std::getenv("SIRAD_BANDS")) bands_ = std::atoi(env);
    if (bands_ <= 0) bands_ = info_.is_cpu ? static_cast<int>(8 * info_.compute_units) : 1 << 30;

    // Geometry: vertices relative to the bounding-sphere centre, patches as uint4.
    std::vector<glm::vec4> verts = centred_vertices(mesh);
    std::vector<cl_uint4> tris(n_);
    for (std::size_t j = 0; j < n_; ++j)
      tris[j] = {{mesh.patches[j][0], mesh.patches[j][1], mesh.patches[j][2], 0u}};
    vertices_ = cl::Buffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, verts.size() * sizeof(glm::vec4), verts.data());
    patches_ = cl::Buffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, tris.size() * sizeof(cl_uint4), tris.data());
    params_ = cl::Buffer(context_, CL_MEM_READ_ONLY, sizeof(SiradBundle));
    projected_ = cl::Buffer(context_, CL_MEM_READ_WRITE, n_ * sizeof(SiradProjected));
    rows_ = cl::Buffer(context_, CL_MEM_READ_WRITE, n_ * sizeof(cl_int2));
    radiance_ = cl::Buffer(context_, CL_MEM_READ_ONLY, n_ * sizeof(glm::vec4));
    gathered_ = cl::Buffer(context_, CL_MEM_WRITE_ONLY, n_ * sizeof(glm::vec4));
    hits_ = cl::Buffer(context_, CL_MEM_WRITE_ONLY, n_ * sizeof(cl_uint));
    status_ = cl::Buffer(context_, CL_MEM_READ_WRITE, 2 * sizeof(cl_uint));
  }

  std::string description() const override {
    return fmt::format("{} / {}", info_.platform_name, info_.device_name);
  }

  void run(const SiradBundle& bundle, std::span<const glm::vec4> radiance, BundleResult& result) override {
    if (radiance.size() != n_) fail("bundle engine: {} radiance values for {} patches", radiance.size(), n_);
    try {
      run_cl(bundle, radiance, result);
    } catch (const cl::Error& e) {
      fail("OpenCL on {}: {}", description(), describe_cl_error(e));
    }
  }

 private:
  void allocate(int grid, uint32_t capacity, int bands) {
    if (grid == grid_ && capacity <= capacity_ && bands == allocated_bands_) return;
    std::size_t cells = static_cast<std::size_t>(grid) * grid;
    cell_count_ = cl::Buffer(context_, CL_MEM_READ_WRITE, cells * sizeof(cl_uint));
    cell_start_ = cl::Buffer(context_, CL_MEM_READ_WRITE, (cells + 1) * sizeof(cl_uint));
    band_total_ = cl::Buffer(context_, CL_MEM_READ_WRITE, static_cast<std::size_t>(bands) * sizeof(cl_uint));
    crossings_ = cl::Buffer(context_, CL_MEM_READ_WRITE, std::max<std::size_t>(capacity, 1) * sizeof(SiradCrossing));
    grid_ = grid;
    capacity_ = capacity;
    allocated_bands_ = bands;
  }

  void run_cl(const SiradBundle& bundle, std::span<const glm::vec4> radiance, BundleResult& result) {
    params_host_ = bundle;
    int bands = std::min(bands_, bundle.grid);
    params_host_.rows_per_band = (bundle.grid + bands - 1) / bands;
    params_host_.bands = (bundle.grid + params_host_.rows_per_band - 1) / params_host_.rows_per_band;
    allocate(bundle.grid, bundle.capacity, params_host_.bands);

    cl_uint n = static_cast<cl_uint>(n_);
    queue_.enqueueWriteBuffer(params_, CL_FALSE, 0, sizeof(SiradBundle), &params_host_);
    queue_.enqueueWriteBuffer(radiance_, CL_FALSE, 0, n_ * sizeof(glm::vec4), radiance.data());

    cl::NDRange patch_global(round_up(std::max<std::size_t>(n_, 1), kPatchGroup));
    cl::NDRange patch_local(kPatchGroup);
    cl::NDRange band_global(static_cast<std::size_t>(params_host_.bands));
    // One work-item per work-group on a CPU (each is a thread's worth of rows); the
    // runtime's choice elsewhere.
    cl::NDRange band_local = info_.is_cpu ? cl::NDRange(1) : cl::NullRange;

    project_.setArg(0, vertices_);
    project_.setArg(1, patches_);
    project_.setArg(2, n);
    project_.setArg(3, params_);
    project_.setArg(4, projected_);
    project_.setArg(5, rows_);
    queue_.enqueueNDRangeKernel(project_, cl::NullRange, patch_global, patch_local, nullptr, &events_[0]);

    count_.setArg(0, projected_);
    count_.setArg(1, rows_);
    count_.setArg(2, n);
    count_.setArg(3, params_);
    count_.setArg(4, cell_count_);
    count_.setArg(5, band_total_);
    queue_.enqueueNDRangeKernel(count_, cl::NullRange, band_global, band_local, nullptr, &events_[1]);

    fill_.setArg(0, projected_);
    fill_.setArg(1, rows_);
    fill_.setArg(2, n);
    fill_.setArg(3, params_);
    fill_.setArg(4, cell_count_);
    fill_.setArg(5, band_total_);
    fill_.setArg(6, cell_start_);
    fill_.setArg(7, crossings_);
    fill_.setArg(8, status_);
    queue_.enqueueNDRangeKernel(fill_, cl::NullRange, band_global, band_local, nullptr, &events_[2]);

    // Gather: on a CPU each work-item takes a run of patches (no divergent lanes); elsewhere
    // one patch per work-item.
    cl_uint per_item = 1;
    cl::NDRange gather_global = patch_global, gather_local = patch_local;
    if (info_.is_cpu) {
      std::size_t items = std::min<std::size_t>(std::max<std::size_t>(n_, 1), 64 * info_.compute_units);
      per_item = static_cast<cl_uint>((n_ + items - 1) / items);
      gather_global = cl::NDRange(items);
      gather_local = cl::NDRange(1);
    }
    gather_.setArg(0, projected_);
    gather_.setArg(1, n);
    gather_.setArg(2, per_item);
    gather_.setArg(3, params_);
    gather_.setArg(4, cell_start_);
    gather_.setArg(5, crossings_);
    gather_.setArg(6, status_);
    gather_.setArg(7, radiance_);
    gather_.setArg(8, gathered_);
    gather_.setArg(9, hits_);
    queue_.enqueueNDRangeKernel(gather_, cl::NullRange, gather_global, gather_local, nullptr, &events_[3]);

    result.gathered.resize(n_);
    result.hits.resize(n_);
    cl_uint status[2] = {0, 0};
    queue_.enqueueReadBuffer(gathered_, CL_FALSE, 0, n_ * sizeof(glm::vec4), result.gathered.data());
    queue_.enqueueReadBuffer(hits_, CL_FALSE, 0, n_ * sizeof(cl_uint), result.hits.data());
    queue_.enqueueReadBuffer(status_, CL_TRUE, 0, sizeof(status), status);
    if (status[0] != 0)
      fail("bundle needs {} crossings but the buffer holds {} (capacity bound violated)", status[1], bundle.capacity);
    result.crossings = status[1];
    if (profile_) {
      for (int k = 0; k < 4; ++k)
        kernel_ns_[k] += events_[k].getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                         events_[k].getProfilingInfo<CL_PROFILING_COMMAND_START>();
      if (++profiled_ % 10 == 0)
        std::fprintf(stderr, "sirad profile (ms/bundle): project %.3f count %.3f fill %.3f gather %.3f\n",
                     kernel_ns_[0] * 1e-6 / profiled_, kernel_ns_[1] * 1e-6 / profiled_,
                     kernel_ns_[2] * 1e-6 / profiled_, kernel_ns_[3] * 1e-6 / profiled_);
    }
  }

  std::size_t n_;
  cl::Device device_;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  cl::Kernel project_, count_, fill_, gather_;
  int bands_ = 0;
  cl::Buffer vertices_, patches_, params_, projected_, rows_, radiance_, gathered_, hits_, status_;
  cl::Buffer cell_count_, cell_start_, band_total_, crossings_;
  int grid_ = 0, allocated_bands_ = 0;
  uint32_t capacity_ = 0;
  SiradBundle params_host_{};
  // SIRAD_PROFILE set: per-kernel device times, printed every 10 bundles.
  bool profile_ = false;
  cl::Event events_[4];
  double kernel_ns_[4] = {0, 0, 0, 0};
  int profiled_ = 0;
};

}  // namespace

std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& options) {
  try {
    return std::make_unique<ClEngine>(mesh, options);
  } catch (const cl::Error& e) {
    fail("OpenCL: {}", describe_cl_error(e));
  }
}

}  // namespace sirad
