// sirad: the OpenCL bundle engine's band path (buffers, launches and read-back for one bundle),
// and make_cl_engine, which chooses a path for the device.
#include "engine/bundle_cl.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "engine/bundle_cl_paths.h"
#include "util/check.h"
#include "util/error.h"

namespace sirad {

namespace {

class ClEngine final : public BundleEngine {
 public:
  ClEngine(const PatchMesh& mesh, const ClEngineOptions& options)
      : mesh_(mesh), n_(mesh.size()), row_capacity_(options.row_capacity),
        list_capacity_(options.list_capacity) {
    device_ = select_device(options.device);
    info_ = describe_device(device_);
    context_ = cl::Context(device_);
    profile_ = options.profile;
    queue_ = cl::CommandQueue(context_, device_, profile_ ? CL_QUEUE_PROFILING_ENABLE : 0);
    // SIRAD_CL_OPTIONS (in kernel_build_options) selects kernel variants by -D flags: experiments.
    cl::Program program = build_program(context_, device_, {"kernels/bundle_types.h", "kernels/bundle.cl"},
                                        kernel_build_options(device_));
    // On a CPU, eight patches per step in float8 lanes; elsewhere one patch per work-item.
    const bool project8 = options.project8.value_or(info_.is_cpu);
    project_ = cl::Kernel(program, project8 ? "project_patches8" : "project_patches");
    transfer_ = cl::Kernel(program, "transfer_band");
    combine_ = cl::Kernel(program, "combine");

    block_lines_ = options.block_lines > 0 ? options.block_lines : 8192;
    bands_ = options.bands;
    // Bands on a CPU: 4 per compute unit (measured against 1, 2 and 8 per unit on 2 cores; see
    // bench/RESULTS.md "Kernel tuning"): enough to balance the threads, few enough that
    // patches spanning two bands and the per-band scan of all patches stay cheap.
    if (bands_ <= 0) bands_ = info_.is_cpu ? static_cast<int>(4 * info_.compute_units) : 1 << 30;
    WorkRuns runs = work_runs(info_, n_);
    patch_items_ = runs.items;
    per_item_ = runs.per_item;

    MeshBuffers geometry = upload_mesh(context_, mesh);
    vertices_ = geometry.vertices;
    patches_ = geometry.patches;
    params_ = cl::Buffer(context_, CL_MEM_READ_ONLY, sizeof(SiradBundle));
    projected_ = cl::Buffer(context_, CL_MEM_READ_WRITE, n_ * sizeof(SiradProjected));
    rows_ = cl::Buffer(context_, CL_MEM_READ_WRITE, n_ * sizeof(cl_int2));
    radiance_ = cl::Buffer(context_, CL_MEM_READ_ONLY, n_ * sizeof(glm::vec4));
    gathered_ = cl::Buffer(context_, CL_MEM_WRITE_ONLY, n_ * sizeof(glm::vec4));
    hits_ = cl::Buffer(context_, CL_MEM_WRITE_ONLY, n_ * sizeof(cl_uint));
  }

  std::string description() const override {
    return fmt::format("{} / {}", info_.platform_name, info_.device_name);
  }

  void run(const SiradBundle& bundle, std::span<const glm::vec4> radiance, BundleResult& result) override {
    SIRAD_CHECK(radiance.size() == n_, "bundle engine: {} radiance values for {} patches", radiance.size(), n_);
    try {
      // A row whose crossings, or a band whose patches, do not fit the scratch make the bundle
      // run again with room for the largest (the result does not depend on the room).
      for (int attempt = 0;; ++attempt) {
        Needed needed = run_cl(bundle, radiance, result);
        if (needed.row == 0 && needed.list == 0) return;
        if (attempt == 2) fail("bundle scratch did not grow ({} crossings in a row, {} patches in a band)", needed.row, needed.list);
        if (needed.row) row_capacity_ = needed.row + needed.row / 4 + 1024;
        if (needed.list) list_capacity_ = needed.list + needed.list / 4 + 1024;
      }
    } catch (const cl::Error& e) {
      fail("OpenCL on {}: {}", description(), describe_cl_error(e));
    }
  }

 private:
  // Scratch for `bands` bands: row_capacity_ crossings of one block of rows, list_capacity_
  // patches, line counters for one block.
  void allocate(int grid, int bands, int rows_per_block) {
    uint64_t cap = std::max<uint64_t>(row_capacity_, 1);
    uint64_t lcap = std::min<uint64_t>(std::max<uint64_t>(list_capacity_, 1), std::max<std::size_t>(n_, 1));
    if (cap > 0xffffffffu / static_cast<uint64_t>(bands) || lcap > 0x7fffffffu / static_cast<uint64_t>(bands))
      fail("bundle scratch of {} crossings and {} patches per band x {} bands is beyond 32-bit indexing", cap, lcap, bands);
    if (grid == grid_ && bands == allocated_bands_ && rows_per_block == allocated_block_rows_ &&
        cap == allocated_capacity_ && lcap == allocated_partials_)
      return;
    std::size_t entries = static_cast<std::size_t>(cap) * bands, listed = static_cast<std::size_t>(lcap) * bands;
    band_list_ = cl::Buffer(context_, CL_MEM_READ_WRITE, listed * sizeof(cl_uint));
    e_x_ = cl::Buffer(context_, CL_MEM_READ_WRITE, entries * sizeof(cl_uint));
    e_sort_ = cl::Buffer(context_, CL_MEM_READ_WRITE, entries * sizeof(cl_ulong));
    s_sort_ = cl::Buffer(context_, CL_MEM_READ_WRITE, entries * sizeof(cl_ulong));
    line_count_ = cl::Buffer(context_, CL_MEM_READ_WRITE,
                             static_cast<std::size_t>(bands) * rows_per_block * grid * sizeof(cl_uint));
    partial_patch_ = cl::Buffer(context_, CL_MEM_READ_WRITE, listed * sizeof(cl_uint));
    partial_sum_ = cl::Buffer(context_, CL_MEM_READ_WRITE, listed * sizeof(glm::vec4));
    partial_hits_ = cl::Buffer(context_, CL_MEM_READ_WRITE, listed * sizeof(cl_uint));
    band_radiance_ = cl::Buffer(context_, CL_MEM_READ_WRITE, listed * sizeof(glm::vec4));
    band_stats_ = cl::Buffer(context_, CL_MEM_READ_WRITE, 4 * static_cast<std::size_t>(bands) * sizeof(cl_uint));
    grid_ = grid;
    allocated_bands_ = bands;
    allocated_block_rows_ = rows_per_block;
    allocated_capacity_ = cap;
    allocated_partials_ = lcap;
  }

  // What did not fit in a run: the most crossings of one row and the most patches of one band
  // (0 where everything fitted).
  struct Needed {
    uint64_t row = 0, list = 0;
  };

  // Runs one bundle; says what did not fit, if anything.
  Needed run_cl(const SiradBundle& bundle, std::span<const glm::vec4> radiance, BundleResult& result) {
    params_host_ = bundle;
    int bands = std::min(bands_, bundle.grid);
    params_host_.rows_per_band = (bundle.grid + bands - 1) / bands;
    params_host_.bands = (bundle.grid + params_host_.rows_per_band - 1) / params_host_.rows_per_band;
    // Rows per block of the band pass: as many as fit the budget of lines, at most a band.
    int block_rows = std::clamp(block_lines_ / bundle.grid, 1, params_host_.rows_per_band);
    // First guesses: a block holds at most a few times an even share of the bound on all
    // crossings; a band is reached by a few times its share of the patches.
    if (row_capacity_ == 0) row_capacity_ = 4 * capacity_bound(mesh_, bundle.grid) * block_rows / bundle.grid + 1024;
    if (list_capacity_ == 0) list_capacity_ = 4 * n_ / params_host_.bands + 4096;
    allocate(bundle.grid, params_host_.bands, block_rows);
    params_host_.capacity = static_cast<sirad_u32>(allocated_capacity_);
    params_host_.partial_capacity = static_cast<sirad_u32>(allocated_partials_);

    cl_uint n = static_cast<cl_uint>(n_);
    queue_.enqueueWriteBuffer(params_, CL_FALSE, 0, sizeof(SiradBundle), &params_host_);
    queue_.enqueueWriteBuffer(radiance_, CL_FALSE, 0, n_ * sizeof(glm::vec4), radiance.data());

    cl::NDRange patch_global(patch_items_);
    cl::NDRange one_per_group = info_.is_cpu ? cl::NDRange(1) : cl::NullRange;

    set_args(project_, vertices_, patches_, n, per_item_, params_, projected_, rows_);
    queue_.enqueueNDRangeKernel(project_, cl::NullRange, patch_global, one_per_group, nullptr, &events_[0]);

    set_args(transfer_, projected_, rows_, n, static_cast<cl_int>(block_rows), params_, radiance_, band_list_, e_x_, e_sort_,
             s_sort_, line_count_, partial_patch_, partial_sum_, partial_hits_, band_radiance_, band_stats_);
    queue_.enqueueNDRangeKernel(transfer_, cl::NullRange, cl::NDRange(static_cast<std::size_t>(params_host_.bands)),
                                one_per_group, nullptr, &events_[1]);

    set_args(combine_, rows_, n, per_item_, params_, partial_patch_, partial_sum_, partial_hits_, band_stats_, gathered_, hits_);
    queue_.enqueueNDRangeKernel(combine_, cl::NullRange, patch_global, one_per_group, nullptr, &events_[2]);

    result.gathered.resize(n_);
    result.hits.resize(n_);
    std::vector<cl_uint> stats(4 * static_cast<std::size_t>(params_host_.bands));
    queue_.enqueueReadBuffer(gathered_, CL_FALSE, 0, n_ * sizeof(glm::vec4), result.gathered.data());
    queue_.enqueueReadBuffer(hits_, CL_FALSE, 0, n_ * sizeof(cl_uint), result.hits.data());
    queue_.enqueueReadBuffer(band_stats_, CL_TRUE, 0, stats.size() * sizeof(cl_uint), stats.data());
    uint64_t total = 0;
    Needed needed;
    for (std::size_t k = 0; k < stats.size(); k += 4) {
      if (stats[k] > allocated_capacity_) needed.row = std::max<uint64_t>(needed.row, stats[k]);
      if (stats[k + 2] > allocated_partials_) needed.list = std::max<uint64_t>(needed.list, stats[k + 2]);
      total += stats[k + 3];
    }
    if (needed.row || needed.list) return needed;
    result.crossings = total;
    if (profile_) report_profile();
    return {};
  }

  // SIRAD_PROFILE set: per-kernel device times, printed every 10 bundles.
  void report_profile() {
    for (int k = 0; k < 3; ++k)
      kernel_ns_[k] += events_[k].getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                       events_[k].getProfilingInfo<CL_PROFILING_COMMAND_START>();
    if (++profiled_ % 10 == 0)
      std::fprintf(stderr, "sirad profile (ms/bundle): project %.3f transfer %.3f combine %.3f\n",
                   kernel_ns_[0] * 1e-6 / profiled_, kernel_ns_[1] * 1e-6 / profiled_, kernel_ns_[2] * 1e-6 / profiled_);
  }

  const PatchMesh& mesh_;
  std::size_t n_;
  uint64_t row_capacity_, list_capacity_;
  cl::Device device_;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  cl::Kernel project_, transfer_, combine_;
  int bands_ = 0;
  int block_lines_ = 0;
  std::size_t patch_items_ = 1;
  cl_uint per_item_ = 1;
  cl::Buffer vertices_, patches_, params_, projected_, rows_, radiance_, gathered_, hits_;
  cl::Buffer band_list_, e_x_, e_sort_, s_sort_, line_count_;
  cl::Buffer partial_patch_, partial_sum_, partial_hits_, band_radiance_, band_stats_;
  int grid_ = 0, allocated_bands_ = 0, allocated_block_rows_ = 0;
  uint64_t allocated_capacity_ = 0, allocated_partials_ = 0;
  SiradBundle params_host_{};
  bool profile_ = false;
  cl::Event events_[3];
  double kernel_ns_[3] = {0, 0, 0};
  int profiled_ = 0;
};

}  // namespace

MeshBuffers upload_mesh(const cl::Context& context, const PatchMesh& mesh) {
  std::vector<glm::vec4> verts = centred_vertices(mesh);
  std::vector<cl_uint4> tris(std::max<std::size_t>(mesh.size(), 1), cl_uint4{});
  for (std::size_t j = 0; j < mesh.size(); ++j) tris[j] = {{mesh.patches[j][0], mesh.patches[j][1], mesh.patches[j][2], 0u}};
  return {cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, verts.size() * sizeof(glm::vec4), verts.data()),
          cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, tris.size() * sizeof(cl_uint4), tris.data())};
}

TransferPath parse_transfer_path(const std::string& name) {
  if (name == "band") return TransferPath::band;
  if (name == "wide") return TransferPath::wide;
  fail("unknown transfer path '{}' (band, wide)", name);
}

const char* to_string(TransferPath path) { return path == TransferPath::band ? "band" : "wide"; }

ClEngineOptions with_environment(ClEngineOptions o) {
  auto positive = [](const char* name) {
    const char* env = std::getenv(name);
    return env ? std::max(0, std::atoi(env)) : 0;
  };
  if (o.bands <= 0) o.bands = positive("SIRAD_BANDS");
  if (o.block_lines <= 0) o.block_lines = positive("SIRAD_BLOCK_LINES");
  if (!o.project8)
    if (const char* env = std::getenv("SIRAD_PROJECT8")) o.project8 = std::atoi(env) != 0;
  o.profile = o.profile || std::getenv("SIRAD_PROFILE") != nullptr;
  if (!o.path)
    if (const char* env = std::getenv("SIRAD_PATH")) {
      try {
        o.path = parse_transfer_path(env);
      } catch (const Error& e) {
        fail("SIRAD_PATH: {}", e.what());
      }
    }
  return o;
}

std::unique_ptr<BundleEngine> make_cl_engine(const PatchMesh& mesh, const ClEngineOptions& given) {
  const ClEngineOptions options = with_environment(given);
  try {
    const TransferPath path = options.path.value_or(describe_device(select_device(options.device)).is_cpu ? TransferPath::band
                                                                                                          : TransferPath::wide);
    if (path == TransferPath::wide) return make_wide_engine(mesh, options);
    return std::make_unique<ClEngine>(mesh, options);
  } catch (const cl::Error& e) {
    fail("OpenCL: setting up {} patches on the device failed: {}", mesh.size(), describe_cl_error(e));
  }
}

}  // namespace sirad
