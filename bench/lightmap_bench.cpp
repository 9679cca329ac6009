// sirad bench: a lightmap (NAME-lightmap.exr of `sirad bake`) against Cycles' bake of the same
// layout (bench/cycles/bake_glb.py of NAME-baked.glb), texel by texel. Prints one CSV row:
//   texels     the texels compared: covered by Cycles' bake with all eight neighbours covered too
//              (a texel on a chart's edge is part outside it: Cycles bakes its centre, sirad the
//              part inside), wholly on a face no solid covers in sirad's (every sample kept: the
//              EXR's coverage layer, where it has one; Cycles bakes the light inside a wall
//              standing on a floor, sirad fills such texels from their visible neighbours), lit
//              in both, emitters left out (their texels are mostly emission);
//   ratio      the sums' ratio less 1 (the lightmap's mean brightness against Cycles');
//   rel_rms    the RMS of the per-texel relative difference of the luminance (Rec. 709);
//   rel_rms_net the same less Cycles' own noise, with two bakes of other seeds (--reference2):
//              their mean is the reference and (a - b)^2 / 4 its variance, subtracted;
//   median, p90 the per-texel relative difference's percentiles;
//   estimate   the RMS of sirad's own per-texel error estimate (the EXR's `error` layer)
//              relative to the reference: against rel_rms_net, how honest it is;
//   charts     the charts compared: 4-connected groups of at least kChartTexels compared texels
//              whose reference mean is at least kChartFloor of the median texel (a chart under a
//              wall, dark to 1e-3 in both, says nothing relative);
//   chart_rms  the texel-weighted RMS of their sums' ratios less 1: a chart's bias, which its
//              texels' noise hides in rel_rms (per-texel noise averages out over a chart);
//   charts_off those off by more than 2 % and by three times their reference's own noise (the two
//              bakes' sums differ by twice it), listed on stderr with their place in the atlas.
//
//   sirad_bench_lightmap --lightmap NAME-lightmap.exr --reference C0.exr [--reference2 C2.exr]
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench/exr_rgb.h"
#include "util/error.h"

using namespace sirad;

using bench::luminance;

constexpr std::size_t kChartTexels = 50;
constexpr double kChartFloor = 0.02;

int main(int argc, char** argv) {
  CLI::App app{"A lightmap against Cycles' bake of its layout, texel by texel (CSV)"};
  std::string lightmap, reference, reference2;
  double emitter_above = 0;
  app.add_option("--lightmap", lightmap, "sirad bake's NAME-lightmap.exr")->required();
  app.add_option("--reference", reference, "Cycles' bake (bench/cycles/bake_glb.py)")->required();
  app.add_option("--reference2", reference2, "A second bake of another seed");
  app.add_option("--emitter-above", emitter_above,
                 "Leave out texels whose reference luminance is above this (emitters; default: 4 times the 99th percentile)");
  CLI11_PARSE(app, argc, argv);
  try {
    const Image mine = bench::read_rgb(lightmap), error = bench::read_rgb(lightmap, "error");
    std::vector<float> coverage;  // empty: a lightmap without the layer (every texel counts)
    {
      Imf::InputFile in(lightmap.c_str());
      int cw = 0, ch = 0;
      if (in.header().channels().findChannel("coverage.R")) coverage = bench::read_channel(lightmap, "coverage.R", cw, ch);
    }
    const Image a = bench::read_rgb(reference);
    int w = 0, h = 0;
    const std::vector<float> alpha = bench::read_channel(reference, "A", w, h);
    if (a.width != mine.width || a.height != mine.height)
      fail("{} is {}x{}, the lightmap {}x{}", reference, a.width, a.height, mine.width, mine.height);
    std::optional<Image> b;
    std::vector<float> alpha2;
    if (!reference2.empty()) {
      b = bench::read_rgb(reference2);
      alpha2 = bench::read_channel(reference2, "A", w, h);
      if (b->width != a.width || b->height != a.height) fail("the two references differ in size");
    }
    const int W = a.width, H = a.height;
    const auto covered = [&](int x, int y) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      return alpha[i] > 0.5f && (alpha2.empty() || alpha2[i] > 0.5f);
    };
    std::vector<double> ref(a.pixels.size()), var(a.pixels.size(), 0.0);
    for (std::size_t i = 0; i < ref.size(); ++i) {
      ref[i] = luminance(a.pixels[i]);
      if (b) {
        const double other = luminance(b->pixels[i]), d = ref[i] - other;
        ref[i] = 0.5 * (ref[i] + other);
        var[i] = d * d / 4.0;
      }
    }
    if (!(emitter_above > 0)) {
      std::vector<double> lit;
      for (double y : ref)
        if (y > 0) lit.push_back(y);
      if (lit.empty()) fail("{}: no lit texel", reference);
      std::nth_element(lit.begin(), lit.begin() + static_cast<std::ptrdiff_t>(0.99 * (lit.size() - 1)), lit.end());
      emitter_above = 4.0 * lit[static_cast<std::size_t>(0.99 * (lit.size() - 1))];
    }
    double sum_mine = 0, sum_ref = 0, sq = 0, sq_var = 0, sq_estimate = 0;
    std::vector<double> rel;
    std::vector<uint8_t> compared(ref.size(), 0);
    for (int y = 1; y + 1 < H; ++y)
      for (int x = 1; x + 1 < W; ++x) {
        bool interior = true;
        for (int dy = -1; dy <= 1 && interior; ++dy)
          for (int dx = -1; dx <= 1 && interior; ++dx) interior = covered(x + dx, y + dy);
        const std::size_t i = static_cast<std::size_t>(y) * W + x;
        const double m = luminance(mine.pixels[i]);
        if (!interior || !(ref[i] > 0) || !(m > 0) || ref[i] > emitter_above || (!coverage.empty() && coverage[i] < 1.0f)) continue;
        const double d = (m - ref[i]) / ref[i];
        sum_mine += m, sum_ref += ref[i];
        sq += d * d, sq_var += var[i] / (ref[i] * ref[i]);
        const double e = luminance(error.pixels[i]) / ref[i];
        sq_estimate += e * e;
        rel.push_back(std::abs(d));
        compared[i] = 1;
      }
    if (rel.empty()) fail("no texel to compare (is the reference a bake of this lightmap's layout?)");
    const double n = static_cast<double>(rel.size());
    std::sort(rel.begin(), rel.end());

    // Charts: flood fill over the compared texels.
    std::vector<double> lit;
    for (std::size_t i = 0; i < ref.size(); ++i)
      if (compared[i]) lit.push_back(ref[i]);
    std::nth_element(lit.begin(), lit.begin() + static_cast<std::ptrdiff_t>(lit.size() / 2), lit.end());
    const double floor = kChartFloor * lit[lit.size() / 2];
    std::vector<uint8_t> seen(ref.size(), 0);  // flooded into a chart
    std::vector<std::size_t> stack, members;
    double chart_sq = 0, chart_texels = 0;
    std::size_t charts = 0, off = 0;
    for (std::size_t start = 0; start < ref.size(); ++start) {
      if (!compared[start] || seen[start]) continue;
      members.clear();
      stack.assign(1, start);
      seen[start] = 1;
      while (!stack.empty()) {
        const std::size_t i = stack.back();
        stack.pop_back();
        members.push_back(i);
        const int x = static_cast<int>(i % W), y = static_cast<int>(i / W);
        const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
        for (int k = 0; k < 4; ++k) {
          if (nx[k] < 0 || ny[k] < 0 || nx[k] >= W || ny[k] >= H) continue;
          const std::size_t j = static_cast<std::size_t>(ny[k]) * W + nx[k];
          if (compared[j] && !seen[j]) seen[j] = 1, stack.push_back(j);
        }
      }
      double m = 0, r = 0, r0 = 0, r2 = 0;
      for (std::size_t i : members) {
        m += luminance(mine.pixels[i]), r += ref[i];
        if (b) r0 += luminance(a.pixels[i]), r2 += luminance(b->pixels[i]);
      }
      const double k = static_cast<double>(members.size());
      if (members.size() < kChartTexels || r / k < floor) continue;
      const double d = m / r - 1, noise = b ? std::abs(r0 - r2) / (2 * r) : 0.0;
      ++charts;
      chart_sq += k * d * d, chart_texels += k;
      if (std::abs(d) > 0.02 && std::abs(d) > 3 * noise) {
        ++off;
        const std::size_t c = members.front();
        std::fprintf(stderr, "chart at %zu,%zu (%zu texels, mean %.4g): %+.2f %% (its reference's noise %.2f %%)\n", c % W, c / W,
                     members.size(), r / k, 100 * d, 100 * noise);
      }
    }
    std::printf("texels,ratio,rel_rms,rel_rms_net,median,p90,estimate,charts,chart_rms,charts_off\n");
    std::printf("%zu,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%zu,%.5f,%zu\n", rel.size(), sum_mine / sum_ref - 1, std::sqrt(sq / n),
                std::sqrt(std::max(0.0, (sq - sq_var) / n)), rel[rel.size() / 2], rel[static_cast<std::size_t>(0.9 * (n - 1))],
                std::sqrt(sq_estimate / n), charts, charts ? std::sqrt(chart_sq / chart_texels) : 0.0, off);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_lightmap: %s\n", e.what());
    return 1;
  }
  return 0;
}
