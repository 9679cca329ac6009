// sirad bench: images against a converged path-traced reference (bench/cycles/render_obj.py
// renders one with Blender's Cycles). Prints CSV, one row per image: the per-pixel relative error
// of the luminance (Rec. 709 weights) at the median, 90th and 99th percentiles and its RMS, light
// pixels (reference luminance above --light-above) left out, with the wall time it took on this
// machine (every core, as Cycles uses them). With a second reference of another seed
// (--reference2) the reference is their mean, and rel_rms_net is the RMS less the reference's own
// noise: the variance of (a - b) / 2 per pixel, (a - b)^2 / 4 relative, subtracted from the
// mean square (a reference of finite samples is never exactly converged). With --noise each final
// gather is rendered twice, with seeds S and S + 1 (--seed S, 1 unless given), and its own noise
// is measured the same way, per pass: noise (combined), noise_direct and noise_indirect are the
// RMS over the compared pixels of the one image's standard deviation, sqrt((a - b)^2 / 2),
// relative to the reference; bias is what is left of rel_rms_net, sqrt(rel_rms_net^2 - noise^2):
// the error no sample count removes. Rows `gather` are the final gather with its irradiance
// cache, `gather-nocache` without (--cache); --solution renders a stored solution instead of
// solving one.
// It also writes each gather's error map (the two seeds' mean against the reference, as a PNG)
// and the same figures per region (material and the axis a surface faces). With
// --reference-passes (a multilayer EXR of the reference's diffuse passes, render_obj.py ...
// passes) each gather's direct and indirect passes are compared with the reference's own: their
// signed mean and RMS differences, relative to the reference's whole luminance.
//
//   sirad_bench_image --reference ref.exr --scene cornell --patches 10000 --bundles 1000,4000
//       --spp 16,64,256 [--candidate cycles-64.exr:12.5 ...]
//
// For each patches x bundles it solves the scene with `sirad render` (solve_s: that process's
// wall time, kernels compiled and cached beforehand by a first run), reads the solution back
// from its PLY and images it: the patches drawn (method "mesh", as sirad render's image) and a
// final gather at each --spp (method "gather"; image_s its own time). A candidate is any other
// EXR of the same view with the seconds it took (Cycles at fewer samples, say): method "file".
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "bench/exr_rgb.h"
#include "io/read_solution.h"
#include "io/write.h"
#include "render/gather.h"
#include "util/error.h"

using namespace sirad;
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::vector<double> luminance(const Image& image) {
  std::vector<double> y(image.pixels.size());
  for (std::size_t i = 0; i < y.size(); ++i)
    y[i] = bench::luminance(image.pixels[i]);
  return y;
}

using bench::read_rgb;

struct Errors {
  double median = 0, p90 = 0, p99 = 0, rms = 0, rms_net = 0;
  double mean = 0;  // the signed mean of (image - reference) / reference: a bias of all one way
  // The ratio of the sums less 1: the mean brightness's error. The per-pixel `mean` above also
  // carries the reference's own noise, E[1 / b] > 1 / E[b]: about ref_var, the mean relative
  // variance of the reference per pixel (0 with one reference), which `ratio` does not.
  double ratio = 0, ref_var = 0;
  std::size_t pixels = 0;
};

// The reference: one image's luminance, or two's mean, and the relative variance of that mean
// per pixel (0 with one).
struct Reference {
  int width = 0, height = 0;
  std::vector<double> y, rel_var;
};

Reference make_reference(const Image& a, const Image* b) {
  Reference r{a.width, a.height, luminance(a), std::vector<double>(a.pixels.size(), 0.0)};
  if (!b) return r;
  if (b->width != a.width || b->height != a.height) fail("the two references differ in size");
  const std::vector<double> yb = luminance(*b);
  for (std::size_t i = 0; i < r.y.size(); ++i) {
    const double d = r.y[i] - yb[i];
    r.y[i] = 0.5 * (r.y[i] + yb[i]);
    r.rel_var[i] = r.y[i] > 0.0 ? d * d / 4.0 / (r.y[i] * r.y[i]) : 0.0;  // var of the mean: var(a - b) / 4
  }
  return r;
}

// Whether pixel i is compared: not a light's (reference luminance above light_above), and in
// `region`'s part `which` where a region is given.
bool counted(const Reference& ref, double light_above, const std::vector<int>* region, int which, std::size_t i) {
  return ref.y[i] > 0.0 && ref.y[i] <= light_above && (!region || (*region)[i] == which);
}

// `region`, if given: only the pixels whose entry is `which`.
Errors compare(const Image& image, const Reference& ref, double light_above, const std::vector<int>* region = nullptr, int which = 0) {
  if (image.width != ref.width || image.height != ref.height)
    fail("image {}x{} against a reference of {}x{}", image.width, image.height, ref.width, ref.height);
  const std::vector<double> a = luminance(image);
  const std::vector<double>& b = ref.y;
  std::vector<double> rel;
  double sq = 0.0, noise = 0.0, sum = 0.0, sum_a = 0.0, sum_b = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!counted(ref, light_above, region, which, i)) continue;
    rel.push_back(std::abs(a[i] - b[i]) / b[i]);
    sum += (a[i] - b[i]) / b[i];
    sum_a += a[i], sum_b += b[i];
    sq += rel.back() * rel.back();
    noise += ref.rel_var[i];
  }
  if (rel.empty()) {
    if (region) return Errors{};  // a region of light pixels only
    fail("no pixel to compare");
  }
  Errors e;
  e.pixels = rel.size();
  e.mean = sum / static_cast<double>(rel.size());
  e.ratio = sum_a / sum_b - 1.0;
  e.ref_var = noise / static_cast<double>(rel.size());
  e.rms = std::sqrt(sq / static_cast<double>(rel.size()));
  e.rms_net = std::sqrt(std::max(0.0, sq - noise) / static_cast<double>(rel.size()));
  std::sort(rel.begin(), rel.end());
  auto at = [&](double q) { return rel[std::min(rel.size() - 1, static_cast<std::size_t>(q * static_cast<double>(rel.size())))]; };
  e.median = at(0.5), e.p90 = at(0.9), e.p99 = at(0.99);
  return e;
}

// An image's own noise: the relative RMS over the compared pixels of sqrt((a - b)^2 / 2), a and b
// the same image of two seeds.
double noise(const Image& a, const Image& b, const Reference& ref, double light_above, const std::vector<int>* region = nullptr,
             int which = 0) {
  const std::vector<double> ya = luminance(a), yb = luminance(b);
  double sq = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < ya.size(); ++i) {
    if (!counted(ref, light_above, region, which, i)) continue;
    const double d = (ya[i] - yb[i]) / ref.y[i];
    sq += d * d / 2.0;
    ++n;
  }
  return n ? std::sqrt(sq / static_cast<double>(n)) : 0.0;
}

// The regions an error is also reported for: each pixel's by the patch its centre sees, one per
// material and axis the patch faces (+x, -x, +y, ...: a wall, a floor and a block's tops), named by
// the material's reflectance; -1 where the centre sees no patch. A scene-wide figure can hide one
// surface far off; these show which.
std::vector<int> regions(const PatchMesh& mesh, int width, int height, std::vector<std::string>& names) {
  std::vector<glm::vec3> id(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const glm::vec3 n = mesh.normal[j];
    int axis = 0;
    for (int c = 1; c < 3; ++c)
      if (std::abs(n[c]) > std::abs(n[axis])) axis = c;
    id[j] = glm::vec3(static_cast<float>(1 + mesh.material[j] * 6 + axis * 2 + (n[axis] < 0.0f ? 1 : 0)), 0.0f, 0.0f);
  }
  const Image seen = render_view(mesh, id, *mesh.camera, width, height, Shading::flat);
  std::vector<int> region(seen.pixels.size());
  names.assign(mesh.materials.size() * 6, "");
  for (std::size_t m = 0; m < mesh.materials.size(); ++m)
    for (int f = 0; f < 6; ++f) {
      const glm::vec3 r = mesh.materials[m].reflectance;
      names[m * 6 + static_cast<std::size_t>(f)] = fmt::format("rho {:.2f} {:.2f} {:.2f} {}{}", r.x, r.y, r.z, "+-"[f % 2], "xyz"[f / 2]);
    }
  for (std::size_t i = 0; i < region.size(); ++i) region[i] = static_cast<int>(seen.pixels[i].x) - 1;
  return region;
}

// The signed error of the mean of two seeds' images, relative to the reference, as a PNG: red
// where the image is too bright, blue where too dark, full at 5 %; grey where not compared.
void write_error_map(const std::string& path, const Image& a, const Image& b, const Reference& ref, double light_above) {
  const std::vector<double> ya = luminance(a), yb = luminance(b);
  Image map{a.width, a.height, std::vector<glm::vec3>(a.pixels.size(), glm::vec3(0.2f))};
  for (std::size_t i = 0; i < ya.size(); ++i) {
    if (!counted(ref, light_above, nullptr, 0, i)) continue;
    const double e = ((ya[i] + yb[i]) / 2.0 - ref.y[i]) / ref.y[i] / 0.05;
    map.pixels[i] = glm::vec3(static_cast<float>(std::clamp(e, 0.0, 1.0)), 0.0f, static_cast<float>(std::clamp(-e, 0.0, 1.0)));
  }
  write_png(path, map);
}

struct Noise {
  double combined = 0, direct = 0, indirect = 0;
};

// A path tracer's own split of the reference (render_obj.py ... passes), as sirad's passes: what
// the camera sees emitted plus the light reflected straight from the emitters, Emit + DiffDir x
// DiffCol, and the rest, DiffInd x DiffCol.
struct ReferencePasses {
  Image direct, indirect;
};

ReferencePasses read_passes(const std::string& path) {
  const Image dir = read_rgb(path, "ViewLayer.DiffDir"), ind = read_rgb(path, "ViewLayer.DiffInd"), col = read_rgb(path, "ViewLayer.DiffCol"),
              emit = read_rgb(path, "ViewLayer.Emit");
  for (const Image* p : {&ind, &col, &emit})
    if (p->width != dir.width || p->height != dir.height) fail("{}: its passes differ in size", path);
  ReferencePasses r{dir, ind};
  for (std::size_t i = 0; i < col.pixels.size(); ++i) {
    r.direct.pixels[i] = r.direct.pixels[i] * col.pixels[i] + emit.pixels[i];
    r.indirect.pixels[i] *= col.pixels[i];
  }
  return r;
}

// How far a pass is from the reference's same pass, relative to the reference's whole
// luminance (so that the two passes' errors add up to the image's): the signed mean and the RMS.
struct PassErrors {
  double direct_mean = 0, direct_rms = 0, indirect_mean = 0, indirect_rms = 0;
};

PassErrors pass_errors(const GatherPasses& g, const ReferencePasses& rp, const Reference& ref, double light_above,
                       const std::vector<int>* region = nullptr, int which = 0) {
  const std::vector<double> gd = luminance(g.direct), gi = luminance(g.indirect), rd = luminance(rp.direct), ri = luminance(rp.indirect);
  double sd = 0, sqd = 0, si = 0, sqi = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < gd.size(); ++i) {
    if (!counted(ref, light_above, region, which, i)) continue;
    const double d = (gd[i] - rd[i]) / ref.y[i], e = (gi[i] - ri[i]) / ref.y[i];
    sd += d, sqd += d * d, si += e, sqi += e * e;
    ++n;
  }
  if (n == 0) return {};
  const double k = 1.0 / static_cast<double>(n);
  return {sd * k, std::sqrt(sqd * k), si * k, std::sqrt(sqi * k)};
}

void row(const std::string& method, const std::string& patches, const std::string& bundles, int spp, double solve_s,
         double image_s, const Errors& e, const std::optional<Noise>& n = std::nullopt,
         const std::optional<PassErrors>& pe = std::nullopt) {
  std::printf("%s,%s,%s,%d,%.3f,%.3f,%.3f,%.5f,%.5f,%.5f,%.5f,%.5f", method.c_str(), patches.c_str(), bundles.c_str(), spp,
              solve_s, image_s, solve_s + image_s, e.median, e.p90, e.p99, e.rms, e.rms_net);
  std::printf(",%.5f", e.mean);
  if (n)
    std::printf(",%.5f,%.5f,%.5f,%.5f", n->combined, n->direct, n->indirect,
                std::sqrt(std::max(0.0, e.rms_net * e.rms_net - n->combined * n->combined)));
  else
    std::printf(",,,,");
  if (pe)
    std::printf(",%.5f,%.5f,%.5f,%.5f", pe->direct_mean, pe->direct_rms, pe->indirect_mean, pe->indirect_rms);
  else
    std::printf(",,,,");
  std::printf(",%.5f,%.5f\n", e.ratio, e.ref_var);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sirad_bench_image: images against a converged reference (CSV)"};
  std::string reference, reference2, reference_passes, solution, scene = "cornell", sirad = SIRAD_BINARY, work = "bench-image";
  std::vector<std::string> patches{"10000"}, bundles{"1000"};  // as sirad render takes them, and as the CSV shows them
  std::vector<int> spp{16, 64};
  std::vector<std::string> cache{"on"};
  uint64_t seed = 1;
  std::vector<std::string> candidates;
  double light_above = 3.0;
  bool measure_noise = false;
  app.add_option("--reference", reference, "The converged reference (EXR, linear RGB)")->required();
  app.add_option("--reference2", reference2, "A second reference of another seed: the mean is the reference, its noise is measured");
  app.add_option("--scene", scene, "The scene (as sirad render takes it)")->capture_default_str();
  app.add_option("--solution", solution, "A stored solution (PLY) to render instead of solving (--patches and --bundles then name it in the CSV only)");
  app.add_option("--patches", patches, "Patch counts, comma-separated")->delimiter(',')->capture_default_str();
  app.add_option("--bundles", bundles, "Bundle budgets, comma-separated")->delimiter(',')->capture_default_str();
  app.add_option("--spp", spp, "Final gather samples per pixel, comma-separated")->delimiter(',')->capture_default_str();
  app.add_option("--cache", cache, "The final gather's irradiance cache, comma-separated: on, off (each sample's own gather ray)")
      ->delimiter(',')
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--seed", seed, "The final gathers' seed (with --noise, seed + 1 for the second)")->capture_default_str();
  app.add_option("--candidate", candidates, "Another image to score: FILE.exr:SECONDS");
  app.add_option("--light-above", light_above, "Reference luminance above which a pixel is the light's, left out")->capture_default_str();
  app.add_option("--reference-passes", reference_passes,
                 "A multilayer EXR of the reference's diffuse passes (render_obj.py ... passes): each final gather's direct and indirect passes against them");
  app.add_flag("--noise", measure_noise, "Render each final gather with a second seed too and split its error into noise (per pass) and bias");
  app.add_option("--sirad", sirad, "The sirad program")->capture_default_str();
  app.add_option("--work", work, "Folder for the solutions")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    const Image ref_image = read_rgb(reference);
    std::optional<Image> second;
    if (!reference2.empty()) second = read_rgb(reference2);
    const Reference ref = make_reference(ref_image, second ? &*second : nullptr);
    std::optional<ReferencePasses> passes;
    if (!reference_passes.empty()) {
      passes = read_passes(reference_passes);
      if (passes->direct.width != ref.width || passes->direct.height != ref.height)
        fail("{}: passes of {}x{} for a reference of {}x{}", reference_passes, passes->direct.width, passes->direct.height, ref.width,
             ref.height);
    }
    if (!solution.empty() && (patches.size() != 1 || bundles.size() != 1))
      fail("--solution {}: one solution, so one --patches and one --bundles to name it", solution);
    fs::create_directories(work);
    std::printf("method,patches,bundles,spp,solve_s,image_s,total_s,median,p90,p99,rel_rms,rel_rms_net,mean,noise,noise_direct,noise_indirect,bias,direct_mean,direct_rms,indirect_mean,indirect_rms,ratio,ref_var\n");
    for (const std::string& c : candidates) {
      const auto colon = c.rfind(':');
      if (colon == std::string::npos) fail("--candidate {}: FILE.exr:SECONDS", c);
      row("file:" + fs::path(c.substr(0, colon)).filename().string(), "", "", 0, 0.0, std::stod(c.substr(colon + 1)),
          compare(read_rgb(c.substr(0, colon)), ref, light_above));
    }
    for (const std::string& p : patches)
      for (const std::string& k : bundles) {
        // Named after the scene's file (a path's stem: the outputs stay in --work, never beside the scene).
        const std::string out = (fs::path(work) / fmt::format("{}-{}-{}", fs::path(scene).stem().string(), p, k)).string();
        double solve_s = 0.0;
        if (solution.empty()) {
          const std::string cmd = fmt::format("'{}' render {} --patches {} --bundles {} --width {} --height {} -q --out '{}' >/dev/null", sirad,
                                              scene, p, k, ref.width, ref.height, out);
          const auto t0 = Clock::now();
          const int rc = std::system(cmd.c_str());
          solve_s = since(t0);
          if (rc != 0) fail("{}: exit {}", cmd, rc);
        }
        Solution s = read_solution(solution.empty() ? out + ".ply" : solution);
        const auto t1 = Clock::now();
        int side = std::clamp(4096 / std::max(ref.width, ref.height), 1, 4);
        const Image mesh = render_view_antialiased(s.mesh, s.radiosity, *s.mesh.camera, ref.width, ref.height, Shading::gouraud, side);
        row("mesh", p, k, side * side, solve_s, since(t1), compare(mesh, ref, light_above));
        std::vector<std::string> names;  // the regions (--noise), the same for every --spp
        const std::vector<int> region = measure_noise ? regions(s.mesh, ref.width, ref.height, names) : std::vector<int>{};
        for (const std::string& mode : cache)
        for (const int n : spp) {
          GatherOptions o{.width = ref.width, .height = ref.height, .spp = n, .seed = seed, .cache = mode == "on"};
          const std::string method = mode == "on" ? "gather" : "gather-nocache";
          const auto t2 = Clock::now();
          GatherPasses g = FinalGather(s.mesh, s.radiosity, o).render(*s.mesh.camera);
          const double image_s = since(t2);
          std::optional<Noise> split;
          GatherPasses h;
          if (measure_noise) {
            o.seed = seed + 1;
            h = FinalGather(s.mesh, s.radiosity, o).render(*s.mesh.camera);
            split = Noise{noise(g.combined, h.combined, ref, light_above), noise(g.direct, h.direct, ref, light_above),
                      noise(g.indirect, h.indirect, ref, light_above)};
          }
          std::optional<PassErrors> pe;
          if (passes) pe = pass_errors(g, *passes, ref, light_above);
          row(method, p, k, o.spp, solve_s, image_s, compare(g.combined, ref, light_above), split, pe);
          if (measure_noise) {
            write_error_map(out + fmt::format("-{}{}-error.png", method, n), g.combined, h.combined, ref, light_above);
            for (int r = 0; r < static_cast<int>(names.size()); ++r) {
              if (std::count(region.begin(), region.end(), r) < 64) continue;  // too few pixels to say
              const Errors e = compare(g.combined, ref, light_above, &region, r);
              if (e.pixels == 0) continue;
              row(method + ":" + names[static_cast<std::size_t>(r)], p, k, o.spp, solve_s, image_s, e,
                  Noise{noise(g.combined, h.combined, ref, light_above, &region, r), noise(g.direct, h.direct, ref, light_above, &region, r),
                        noise(g.indirect, h.indirect, ref, light_above, &region, r)},
                  passes ? std::optional<PassErrors>(pass_errors(g, *passes, ref, light_above, &region, r)) : std::nullopt);
            }
          }
          write_exr(out + fmt::format("-{}{}.exr", method, n), g.combined, {});
          if (measure_noise) write_exr(out + fmt::format("-{}{}-seed{}.exr", method, n, seed + 1), h.combined, {});
        }
      }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_image: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
