// sirad: the first shot's view on an OpenCL device (kernels/shot.cl): buffers, the launches and
// the read-back of the image per shot. Patches are projected and rasterised in blocks of
// kShotBlock, so the scratch (10 projected triangles of 112 bytes per patch: 5 faces, up to
// two after the near clip) is a block's: 147 MB however large the mesh (1.1 KB per patch
// before, the most of a node's memory at a million patches).
#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "engine/bundle_cl.h"
#include "engine/opencl.h"
#include "engine/shot.h"
#include "util/error.h"

namespace sirad {

namespace {

constexpr std::size_t kShotBlock = 131072;  // patches per block of project_shot and raster_shot

class ClShotEngine final : public ShotEngine {
 public:
  ClShotEngine(const PatchMesh& mesh, const std::string& device, bool profile, std::size_t block)
      : n_(mesh.size()), block_(std::max<std::size_t>(1, std::min(n_, block ? block : kShotBlock))) {
    device_ = select_device(device);
    info_ = describe_device(device_);
    max_alloc_ = device_.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
    context_ = cl::Context(device_);
    profile_ = profile;
    queue_ = cl::CommandQueue(context_, device_, profile_ ? CL_QUEUE_PROFILING_ENABLE : 0);
    cl::Program program = build_program(
        context_, device_, {"kernels/bundle_types.h", "kernels/shot_types.h", "kernels/bundle.cl", "kernels/shot.cl"},
        kernel_build_options(device_));
    vertex_kernel_ = cl::Kernel(program, "shot_vertices");
    project_ = cl::Kernel(program, "project_shot");
    raster_ = cl::Kernel(program, "raster_shot");
    WorkRuns patch_runs = work_runs(info_, block_);
    patch_items_ = patch_runs.items;
    per_item_ = patch_runs.per_item;
    std::vector<glm::vec4> verts = centred_vertices(mesh);
    nv_ = verts.size();
    WorkRuns vertex_runs = work_runs(info_, nv_);
    vertex_items_ = vertex_runs.items;
    per_vertex_item_ = vertex_runs.per_item;
    std::vector<cl_uint4> tris(n_);
    for (std::size_t j = 0; j < n_; ++j) tris[j] = {{mesh.patches[j][0], mesh.patches[j][1], mesh.patches[j][2], 0u}};
    vertices_ = cl::Buffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, std::max<std::size_t>(verts.size(), 1) * sizeof(glm::vec4), verts.data());
    patches_ = cl::Buffer(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, std::max<std::size_t>(n_, 1) * sizeof(cl_uint4), tris.data());
    params_ = cl::Buffer(context_, CL_MEM_READ_ONLY, sizeof(SiradShot));
    face_coords_ = cl::Buffer(context_, CL_MEM_READ_WRITE, std::max<std::size_t>(5 * nv_, 1) * sizeof(glm::vec4));
    projected_ = cl::Buffer(context_, CL_MEM_READ_WRITE, 10 * block_ * sizeof(SiradProjected));
    rows_ = cl::Buffer(context_, CL_MEM_READ_WRITE, 10 * block_ * sizeof(cl_int2));
  }

  std::string description() const override { return fmt::format("{} / {}", info_.platform_name, info_.device_name); }

  void render(const SiradShot& shot, std::vector<uint32_t>& image) override {
    try {
      for (int attempt = 0;; ++attempt) {
        uint64_t needed = render_cl(shot, image);
        if (needed == 0) return;
        if (attempt == 2) fail("shot scratch did not grow ({} triangles in a band)", needed);
        capacity_ = needed + needed / 4 + 1024;
      }
    } catch (const cl::Error& e) {
      fail("OpenCL on {}: {}", description(), describe_cl_error(e));
    }
  }

 private:
  // Renders one shot; returns the triangles of the fullest band if they did not fit, else 0.
  uint64_t render_cl(const SiradShot& shot, std::vector<uint32_t>& image) {
    const int H = shot.resolution;
    params_host_ = shot;
    // Bands: on a CPU a few per compute unit over the 3 H rows, each within one face.
    int target = info_.is_cpu ? static_cast<int>(8 * info_.compute_units) : 3 * H;
    int rpb = std::max(1, (3 * H + target - 1) / target);
    rpb = std::min(rpb, H / 2);
    params_host_.rows_per_band = rpb;
    params_host_.bands_top = (H + rpb - 1) / rpb;
    params_host_.bands_side = (H / 2 + rpb - 1) / rpb;
    const int bands = params_host_.bands_top + 4 * params_host_.bands_side;
    if (capacity_ == 0) capacity_ = 4 * 2 * block_ / std::max(1, bands / 5) + 4096;
    capacity_ = std::min<uint64_t>(capacity_, 2 * block_);
    if (capacity_ > 0xffffffffu / static_cast<uint64_t>(bands)) fail("shot scratch of {} triangles x {} bands is beyond 32-bit indexing", capacity_, bands);
    // One busy band sets the capacity of all (a GPU has a band per row): refuse clearly before
    // the device does.
    if (capacity_ * static_cast<uint64_t>(bands) * sizeof(cl_uint) > max_alloc_)
      fail("first shot: {} triangles x {} bands of scratch exceed the device's largest buffer ({} MiB); "
           "lower the shot resolution or the patch count", capacity_, bands, max_alloc_ >> 20);
    params_host_.capacity = static_cast<sirad_u32>(capacity_);
    if (H != allocated_resolution_ || bands != allocated_bands_ || capacity_ != allocated_capacity_) {
      band_list_ = cl::Buffer(context_, CL_MEM_READ_WRITE, static_cast<std::size_t>(capacity_) * bands * sizeof(cl_uint));
      // Each band's z-buffer covers its rows (rows_per_band x H samples).
      const std::size_t zsize = static_cast<std::size_t>(H) * static_cast<std::size_t>(rpb) * bands;
      zbuf_ = cl::Buffer(context_, CL_MEM_READ_WRITE, zsize * sizeof(cl_float));
      zwin_ = cl::Buffer(context_, CL_MEM_READ_WRITE, zsize * sizeof(cl_uint));
      image_ = cl::Buffer(context_, CL_MEM_WRITE_ONLY, shot_pixels(H) * sizeof(cl_uint));
      stats_ = cl::Buffer(context_, CL_MEM_READ_WRITE, static_cast<std::size_t>(bands) * sizeof(cl_uint));
      allocated_resolution_ = H;
      allocated_bands_ = bands;
      allocated_capacity_ = capacity_;
    }
    queue_.enqueueWriteBuffer(params_, CL_FALSE, 0, sizeof(SiradShot), &params_host_);
    cl::NDRange one_per_group = info_.is_cpu ? cl::NDRange(1) : cl::NullRange;
    vertex_kernel_.setArg(0, vertices_);
    vertex_kernel_.setArg(1, static_cast<cl_uint>(nv_));
    vertex_kernel_.setArg(2, per_vertex_item_);
    vertex_kernel_.setArg(3, params_);
    vertex_kernel_.setArg(4, face_coords_);
    queue_.enqueueNDRangeKernel(vertex_kernel_, cl::NullRange, cl::NDRange(vertex_items_), one_per_group);
    project_.setArg(0, face_coords_);
    project_.setArg(1, patches_);
    project_.setArg(4, per_item_);
    for (int arg = 5; const cl::Buffer* b : {&params_, &projected_, &rows_}) project_.setArg(arg++, *b);
    raster_.setArg(0, projected_);
    raster_.setArg(1, rows_);
    for (int arg = 5; const cl::Buffer* b : {&params_, &band_list_, &zbuf_, &zwin_, &image_, &stats_}) raster_.setArg(arg++, *b);
    for (std::size_t first = 0; first < std::max<std::size_t>(n_, 1); first += block_) {
      const cl_uint count = static_cast<cl_uint>(std::min(block_, n_ - std::min(first, n_)));
      const cl_uint stage = (first == 0 ? 1u : 0u) | (first + block_ >= n_ ? 2u : 0u);
      project_.setArg(2, static_cast<cl_uint>(first));
      project_.setArg(3, count);
      queue_.enqueueNDRangeKernel(project_, cl::NullRange, cl::NDRange(patch_items_), one_per_group, nullptr, &events_[0]);
      raster_.setArg(2, static_cast<cl_uint>(first));
      raster_.setArg(3, count);
      raster_.setArg(4, stage);
      queue_.enqueueNDRangeKernel(raster_, cl::NullRange, cl::NDRange(static_cast<std::size_t>(bands)), one_per_group, nullptr,
                                  &events_[1]);
      if (profile_) add_profile();
    }
    std::vector<cl_uint> stats(static_cast<std::size_t>(bands));
    image.resize(shot_pixels(H));
    queue_.enqueueReadBuffer(image_, CL_FALSE, 0, image.size() * sizeof(cl_uint), image.data());
    queue_.enqueueReadBuffer(stats_, CL_TRUE, 0, stats.size() * sizeof(cl_uint), stats.data());
    uint64_t most = *std::max_element(stats.begin(), stats.end());
    if (most > capacity_) return most;
    if (profile_) report_profile();
    return 0;
  }

  // SIRAD_PROFILE set: the two kernels' device times (summed over blocks), printed every 10 shots.
  void add_profile() {
    for (int k = 0; k < 2; ++k) {
      events_[k].wait();
      kernel_ns_[k] += events_[k].getProfilingInfo<CL_PROFILING_COMMAND_END>() - events_[k].getProfilingInfo<CL_PROFILING_COMMAND_START>();
    }
  }
  void report_profile() {
    if (++profiled_ % 10 == 0)
      std::fprintf(stderr, "sirad profile (ms/shot): project %.3f raster %.3f\n", kernel_ns_[0] * 1e-6 / profiled_,
                   kernel_ns_[1] * 1e-6 / profiled_);
  }

  std::size_t n_, block_;
  cl::Device device_;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  cl::Kernel vertex_kernel_, project_, raster_;
  std::size_t nv_ = 0, vertex_items_ = 1;
  cl_uint per_vertex_item_ = 1;
  std::size_t patch_items_ = 1;
  cl_uint per_item_ = 1;
  cl::Buffer vertices_, patches_, params_, face_coords_, projected_, rows_, band_list_, zbuf_, zwin_, image_, stats_;
  SiradShot params_host_{};
  uint64_t capacity_ = 0, allocated_capacity_ = 0, max_alloc_ = 0;
  int allocated_resolution_ = 0, allocated_bands_ = 0;
  bool profile_ = false;
  cl::Event events_[2];
  double kernel_ns_[2] = {0, 0};
  int profiled_ = 0;
};

}  // namespace

std::unique_ptr<ShotEngine> make_cl_shot_engine(const PatchMesh& mesh, const std::string& device, std::size_t block) {
  try {
    // Its one tuning, SIRAD_PROFILE, as the bundle engine reads it (engine/bundle_cl.h).
    return std::make_unique<ClShotEngine>(mesh, device, with_environment({}).profile, block);
  } catch (const cl::Error& e) {
    fail("OpenCL: setting up the first shot for {} patches failed: {}", mesh.size(), describe_cl_error(e));
  }
}

}  // namespace sirad
