// sirad: the OpenCL bundle engine's wide path (kernels/bundle_wide.cl): one work-item per patch,
// per (patch, row) span or per line, for devices with many lanes, and a batch of bundles per
// launch. Buffers stay on the device between batches; per batch the radiance and the bundles go
// up and the sums and two totals come down.
#include <algorithm>
#include <cstdio>

#include "engine/bundle_cl_paths.h"
#include "util/check.h"
#include "util/error.h"

namespace sirad {

namespace {

class WideEngine final : public BundleEngine {
 public:
  WideEngine(const PatchMesh& mesh, const ClEngineOptions& options) : mesh_(mesh), n_(mesh.size()) {
    device_ = select_device(options.device);
    info_ = describe_device(device_);
    context_ = cl::Context(device_);
    profile_ = options.profile;
    queue_ = cl::CommandQueue(context_, device_, profile_ ? CL_QUEUE_PROFILING_ENABLE : 0);
    cl::Program program = build_program(context_, device_,
                                        {"kernels/bundle_types.h", "kernels/bundle.cl", "kernels/bundle_wide.cl"},
                                        kernel_build_options(device_));
    project_ = cl::Kernel(program, "wide_project");
    count_spans_ = cl::Kernel(program, "wide_count_spans");
    count_crossings_ = cl::Kernel(program, "wide_count_crossings");
    emit_ = cl::Kernel(program, "wide_emit");
    gather_ = cl::Kernel(program, "wide_gather_lines");
    sum_ = cl::Kernel(program, "wide_sum_patches");
    scan_reduce_ = cl::Kernel(program, "scan_reduce");
    scan_partials_ = cl::Kernel(program, "scan_partials");
    scan_down_ = cl::Kernel(program, "scan_down");

    MeshBuffers geometry = upload_mesh(context_, mesh);
    vertices_ = geometry.vertices;
    patches_ = geometry.patches;
    radiance_ = cl::Buffer(context_, CL_MEM_READ_ONLY, std::max<std::size_t>(n_, 1) * sizeof(glm::vec4));
    partial_ = cl::Buffer(context_, CL_MEM_READ_WRITE, (kScanItems + 1) * sizeof(cl_uint));
    lengths_ = cl::Buffer(context_, CL_MEM_READ_WRITE, 2 * sizeof(cl_uint));
    span_cap_ = options.span_capacity;
    cross_cap_ = options.crossing_capacity;
    given_capacities_ = span_cap_ > 0 && cross_cap_ > 0;
    span_cap_ = std::max<uint64_t>(span_cap_, 1);
    cross_cap_ = std::max<uint64_t>(cross_cap_, 1);
  }

  // A GPU wants 1e5-1e6 work-items in flight: a batch of about 2^20 patches (a bundle's
  // crossings are a few per patch at the auto grid), in a power of two from 1 to 16 bundles:
  // 16 at 20k patches, 8 at 100k, 1 from a million.
  uint32_t preferred_batch() const override {
    std::size_t b = 16;
    while (b > 1 && b * n_ > (std::size_t{1} << 20)) b /= 2;
    return static_cast<uint32_t>(b);
  }

  std::string description() const override {
    return fmt::format("{} / {} (wide path)", info_.platform_name, info_.device_name);
  }

  void run(const SiradBundle& bundle, std::span<const glm::vec4> radiance, BundleResult& result) override {
    run_batch(std::span<const SiradBundle>(&bundle, 1), radiance, std::span<BundleResult>(&result, 1));
  }

  void run_batch(std::span<const SiradBundle> bundles, std::span<const glm::vec4> radiance,
                 std::span<BundleResult> results) override {
    SIRAD_CHECK(radiance.size() == n_, "bundle engine: {} radiance values for {} patches", radiance.size(), n_);
    SIRAD_CHECK(results.size() == bundles.size(), "run_batch: {} results for {} bundles", results.size(), bundles.size());
    if (bundles.empty()) return;
    for (const SiradBundle& b : bundles)
      SIRAD_CHECK(b.grid == bundles[0].grid, "run_batch: bundles of grids {} and {} in one batch", bundles[0].grid, b.grid);
    const uint64_t lines = static_cast<uint64_t>(bundles[0].grid) * static_cast<uint64_t>(bundles[0].grid);
    if (lines * bundles.size() >= 0xffffffffu || static_cast<uint64_t>(n_) * bundles.size() >= 0xffffffffu)
      fail("a batch of {} bundles of grid {} over {} patches is beyond the wide path's 32-bit numbering", bundles.size(),
           bundles[0].grid, n_);
    try {
      for (int attempt = 0;; ++attempt) {
        Totals t = run_cl(bundles, radiance, results);
        if (t.spans <= span_cap_ && t.crossings <= cross_cap_) return;
        if (attempt == 2) fail("bundle scratch did not grow ({} spans, {} crossings)", t.spans, t.crossings);
        // The crossings counted are all of them only when every span fitted.
        if (t.spans > span_cap_) span_cap_ = t.spans + t.spans / 4 + 1024;
        else cross_cap_ = t.crossings + t.crossings / 4 + 1024;
      }
    } catch (const cl::Error& e) {
      fail("OpenCL on {}: {}", description(), describe_cl_error(e));
    }
  }

 private:
  static constexpr cl_uint kScanItems = 1024;  // work-items of each scan (chunks)

  struct Totals {
    uint64_t spans = 0, crossings = 0;
  };

  void allocate(int grid, std::size_t batch) {
    // Sizes not given: the bounds (no bundle exceeds them; a batch's are B times a bundle's),
    // up to 2^26 entries; beyond that, and from sizes given, the scratch grows to what the
    // bundles need (run_batch).
    if (!given_capacities_ && (grid != grid_ || batch > batch_)) {
      span_cap_ = std::max(span_cap_, std::min<uint64_t>(span_bound(mesh_, grid) * batch, uint64_t{1} << 26));
      cross_cap_ = std::max(cross_cap_, std::min<uint64_t>(capacity_bound(mesh_, grid) * batch, uint64_t{1} << 26));
    }
    if (span_cap_ >= 0xffffffffu || cross_cap_ >= 0xffffffffu)
      fail("bundle scratch of {} spans and {} crossings is beyond 32-bit indexing", span_cap_, cross_cap_);
    if (grid != grid_ || batch > batch_) {
      const std::size_t patches = std::max<std::size_t>(n_ * batch, 1);
      params_ = cl::Buffer(context_, CL_MEM_READ_ONLY, batch * sizeof(SiradBundle));
      projected_ = cl::Buffer(context_, CL_MEM_READ_WRITE, patches * sizeof(SiradProjected));
      rows_ = cl::Buffer(context_, CL_MEM_READ_WRITE, patches * sizeof(cl_int2));
      gathered_ = cl::Buffer(context_, CL_MEM_READ_WRITE, patches * sizeof(glm::vec4));
      hits_ = cl::Buffer(context_, CL_MEM_READ_WRITE, patches * sizeof(cl_uint));
      span_start_ = cl::Buffer(context_, CL_MEM_READ_WRITE, (n_ * batch + 1) * sizeof(cl_uint));
      std::size_t lines = static_cast<std::size_t>(grid) * grid * batch;
      line_count_ = cl::Buffer(context_, CL_MEM_READ_WRITE, lines * sizeof(cl_uint));
      line_start_ = cl::Buffer(context_, CL_MEM_READ_WRITE, (lines + 1) * sizeof(cl_uint));
      queue_.enqueueFillBuffer(line_count_, cl_uint{0}, 0, lines * sizeof(cl_uint));
      grid_ = grid;
      batch_ = batch;
    }
    if (span_cap_ != allocated_spans_) {
      cross_start_ = cl::Buffer(context_, CL_MEM_READ_WRITE, (span_cap_ + 1) * sizeof(cl_uint));
      allocated_spans_ = span_cap_;
    }
    if (cross_cap_ != allocated_crossings_) {
      std::size_t c = std::max<std::size_t>(cross_cap_, 1);
      keys_ = cl::Buffer(context_, CL_MEM_READ_WRITE, c * sizeof(cl_ulong));
      emit_numbers_ = cl::Buffer(context_, CL_MEM_READ_WRITE, c * sizeof(cl_uint));
      seen_ = cl::Buffer(context_, CL_MEM_READ_WRITE, c * sizeof(glm::vec4));
      allocated_crossings_ = cross_cap_;
    }
  }

  // Exclusive scan of min(len[len_at], cap) entries of `in` into `out` (kernels/bundle_wide.cl).
  void scan(const cl::Buffer& in, const cl::Buffer& out, const cl::Buffer& len, cl_uint len_at, cl_uint cap, int pass) {
    const cl::NDRange items(kScanItems), one(group());
    set_args(scan_reduce_, in, len, len_at, cap, partial_);
    queue_.enqueueNDRangeKernel(scan_reduce_, cl::NullRange, items, one, nullptr, &first_[pass]);
    set_args(scan_partials_, partial_, kScanItems);
    queue_.enqueueNDRangeKernel(scan_partials_, cl::NullRange, cl::NDRange(1), cl::NDRange(1));
    set_args(scan_down_, in, out, len, len_at, cap, partial_);
    queue_.enqueueNDRangeKernel(scan_down_, cl::NullRange, items, one, nullptr, &last_[pass]);
  }

  // Enqueues `kernel` as pass `pass` (its event kept for SIRAD_PROFILE).
  void launch(const cl::Kernel& kernel, std::size_t count, int pass) {
    queue_.enqueueNDRangeKernel(kernel, cl::NullRange, global(count), cl::NDRange(group()), nullptr, &first_[pass]);
    last_[pass] = first_[pass];
  }

  // Global size: `count` rounded up to the work-group size.
  cl::NDRange global(std::size_t count) const {
    std::size_t g = group();
    return cl::NDRange(std::max<std::size_t>((count + g - 1) / g * g, g));
  }
  std::size_t group() const { return info_.is_cpu ? 1 : 64; }

  Totals run_cl(std::span<const SiradBundle> bundles, std::span<const glm::vec4> radiance, std::span<BundleResult> results) {
    const std::size_t batch = bundles.size();
    allocate(bundles[0].grid, batch);
    const cl_uint n = static_cast<cl_uint>(n_), b = static_cast<cl_uint>(batch), patches = n * b,
                  span_cap = static_cast<cl_uint>(span_cap_), cross_cap = static_cast<cl_uint>(cross_cap_);
    const cl_uint lines = static_cast<cl_uint>(bundles[0].grid) * static_cast<cl_uint>(bundles[0].grid) * b;
    params_host_.assign(bundles.begin(), bundles.end());
    lengths_host_[0] = patches;
    lengths_host_[1] = lines;
    queue_.enqueueWriteBuffer(params_, CL_FALSE, 0, batch * sizeof(SiradBundle), params_host_.data());
    queue_.enqueueWriteBuffer(lengths_, CL_FALSE, 0, sizeof(lengths_host_), lengths_host_);
    queue_.enqueueWriteBuffer(radiance_, CL_FALSE, 0, n_ * sizeof(glm::vec4), radiance.data());

    set_args(project_, vertices_, patches_, n, b, params_, projected_, rows_);
    launch(project_, patches, 0);

    set_args(count_spans_, rows_, patches, span_start_);
    launch(count_spans_, patches, 1);
    scan(span_start_, span_start_, lengths_, 0, patches, 2);

    set_args(count_crossings_, projected_, rows_, n, b, params_, span_start_, span_cap, cross_start_, line_count_);
    launch(count_crossings_, span_cap_, 3);
    scan(cross_start_, cross_start_, span_start_, patches, span_cap, 4);
    scan(line_count_, line_start_, lengths_, 1, lines, 5);

    set_args(emit_, projected_, rows_, n, b, params_, span_start_, span_cap, cross_start_, line_start_, cross_cap, line_count_,
             keys_, emit_numbers_);
    launch(emit_, span_cap_, 6);

    set_args(gather_, b, params_, line_start_, cross_cap, keys_, emit_numbers_, radiance_, seen_);
    launch(gather_, lines, 7);

    set_args(sum_, n, b, params_, span_start_, span_cap, cross_start_, line_start_, cross_cap, seen_, gathered_, hits_);
    launch(sum_, patches, 8);

    for (std::size_t k = 0; k < batch; ++k) {
      results[k].gathered.resize(n_);
      results[k].hits.resize(n_);
      queue_.enqueueReadBuffer(gathered_, CL_FALSE, k * n_ * sizeof(glm::vec4), n_ * sizeof(glm::vec4), results[k].gathered.data());
      queue_.enqueueReadBuffer(hits_, CL_FALSE, k * n_ * sizeof(cl_uint), n_ * sizeof(cl_uint), results[k].hits.data());
    }
    cl_uint totals[2] = {0, 0};
    queue_.enqueueReadBuffer(span_start_, CL_FALSE, static_cast<std::size_t>(patches) * sizeof(cl_uint), sizeof(cl_uint), &totals[0]);
    queue_.enqueueReadBuffer(line_start_, CL_TRUE, static_cast<std::size_t>(lines) * sizeof(cl_uint), sizeof(cl_uint), &totals[1]);
    Totals t{totals[0], totals[1]};
    if (t.spans <= span_cap_ && t.crossings <= cross_cap_) {
      for (BundleResult& r : results) {  // a bundle's crossings are its patches' hits
        r.crossings = 0;
        for (uint32_t h : r.hits) r.crossings += h;
      }
      if (profile_) report_profile(batch);
    }
    return t;
  }

  // SIRAD_PROFILE set: per-pass device times per bundle (a scan's from its first kernel's start
  // to its last one's end), printed every 10 batches.
  void report_profile(std::size_t batch) {
    for (int k = 0; k < kEvents; ++k)
      kernel_ns_[k] += static_cast<double>(last_[k].getProfilingInfo<CL_PROFILING_COMMAND_END>() -
                                           first_[k].getProfilingInfo<CL_PROFILING_COMMAND_START>());
    profiled_ += static_cast<int>(batch);
    if (++batches_ % 10 != 0) return;
    static const char* const names[kEvents] = {"project", "count_spans", "scan_spans", "count_crossings", "scan_crossings",
                                               "scan_lines", "emit", "gather_lines", "sum_patches"};
    std::string line = fmt::format("sirad profile (ms/bundle, wide path, {} a batch):", batch);
    for (int k = 0; k < kEvents; ++k) line += fmt::format(" {} {:.3f}", names[k], kernel_ns_[k] * 1e-6 / profiled_);
    std::fprintf(stderr, "%s\n", line.c_str());
  }

  static constexpr int kEvents = 9;
  const PatchMesh& mesh_;
  std::size_t n_;
  cl::Device device_;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  cl::Kernel project_, count_spans_, count_crossings_, emit_, gather_, sum_, scan_reduce_, scan_partials_, scan_down_;
  cl::Buffer vertices_, patches_, params_, projected_, rows_, radiance_, gathered_, hits_;
  cl::Buffer span_start_, partial_, lengths_, line_count_, line_start_, cross_start_, keys_, emit_numbers_, seen_;
  uint64_t span_cap_ = 0, cross_cap_ = 0, allocated_spans_ = 0, allocated_crossings_ = 0;
  int grid_ = 0;
  std::size_t batch_ = 0;
  bool given_capacities_ = false;  // ClEngineOptions' first sizes (tests): grown, never reset
  std::vector<SiradBundle> params_host_;
  cl_uint lengths_host_[2] = {0, 0};
  bool profile_ = false;
  cl::Event first_[kEvents], last_[kEvents];
  double kernel_ns_[kEvents] = {};
  int profiled_ = 0, batches_ = 0;  // bundles and batches profiled
};

}  // namespace

std::unique_ptr<BundleEngine> make_wide_engine(const PatchMesh& mesh, const ClEngineOptions& options) {
  return std::make_unique<WideEngine>(mesh, options);
}

}  // namespace sirad
