// sirad bench: random against stratified directions on the Cornell box.
// Relative RMS error per non-emitting patch (area-weighted, solver/metrics.h) of single chain-rule
// runs against a long-run truth (the mean of --truth-runs random runs of --truth-bundles each,
// seeds 1000..), at the checkpoint bundle counts, for --seeds paired seeds (the random and the
// stratified run of a pair share the seed). Also the bias check: the area mean of every run at
// the last checkpoint, per mode. Prints CSV on stdout, a summary on stderr.
//   sirad_bench_directions [--patches N] [--seeds S] [--first-seed F] [--checkpoints 64,256,1024,4096]
//                          [--truth-runs R] [--truth-bundles B] [--device D]
//                          [--interleave G] [--side n]   (override the plan: K = n^2)
//                          [--shots-per-bundle X]       (first shot in the compared runs, not the truth)
//                          [--reference NAME.ref.csv]   (truth from `sirad reference`; its SE as its error)
// The truth's own error inflates the measured error: E|x - t|^2 = Var(x) + Var(t); the summary
// reports the truth's error estimated from its runs' spread and the errors with it subtracted
// in quadrature.
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/reference.h"
#include "solver/solver.h"
#include "util/error.h"

using namespace sirad;

int main(int argc, char** argv) {
  try {
    std::size_t patches = 1000;
    int seeds = 6, truth_runs = 4, first_seed = 1;
    uint64_t truth_bundles = 16384;
    std::vector<uint64_t> checkpoints = {64, 256, 1024, 4096};
    std::string device;
    uint32_t interleave = 0, side = 0;
    std::string truth_file;
    double shots = 0.0;
    std::string reference;
    for (int i = 1; i + 1 < argc; i += 2) {
      std::string k = argv[i], v = argv[i + 1];
      if (k == "--patches") patches = std::stoul(v);
      else if (k == "--seeds") seeds = std::stoi(v);
      else if (k == "--first-seed") first_seed = std::stoi(v);
      else if (k == "--truth-runs") truth_runs = std::stoi(v);
      else if (k == "--truth-bundles") truth_bundles = std::stoull(v);
      else if (k == "--device") device = v;
      else if (k == "--interleave") interleave = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--side") side = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--truth-file") truth_file = v;
      else if (k == "--shots-per-bundle") shots = std::stod(v);
      else if (k == "--reference") reference = v;
      else if (k == "--checkpoints") {
        checkpoints.clear();
        std::stringstream ss(v);
        for (std::string t; std::getline(ss, t, ',');) checkpoints.push_back(std::stoull(t));
      } else fail("unknown option {}", k);
    }
    PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = patches});
    auto engine = make_cl_engine(mesh, {.device = device});
    std::unique_ptr<ShotEngine> shot_engine;
    if (shots > 0) shot_engine = make_cl_shot_engine(mesh, device);
    Sampling plan = sampling_plan(mesh, Directions::stratified);
    if (interleave) plan.interleave = interleave;
    if (side) plan.side = side;
    std::fprintf(stderr, "cornell: %zu patches, grid %d, stratified G = %u, K = %u\n", mesh.size(), auto_grid(mesh),
                 plan.interleave, plan.side * plan.side);

    // Truth: mean of R long random runs (kept in --truth-file, when given, for the next run).
    std::vector<glm::vec3> truth(mesh.size());
    double truth_err = 0.0;
    if (!truth_file.empty()) {
      if (std::FILE* f = std::fopen(truth_file.c_str(), "rb")) {
        bool ok = std::fread(&truth_err, sizeof truth_err, 1, f) == 1 &&
                  std::fread(truth.data(), sizeof(glm::vec3), truth.size(), f) == truth.size();
        std::fclose(f);
        if (!ok) fail("{}: short truth file", truth_file);
        truth_runs = 0;
        std::fprintf(stderr, "truth from %s, its own relative RMS error ~%.4f\n", truth_file.c_str(), truth_err);
      }
    }
    if (!reference.empty()) {
      ReferenceSolution ref = read_reference(reference, mesh);
      double se2 = 0, b2 = 0;
      for (std::size_t j = 0; j < mesh.size(); ++j) {
        truth[j] = glm::vec3(ref.radiosity[j]);
        glm::vec3 e = mesh.emission(j);
        if (e.x + e.y + e.z > 0) continue;
        se2 += mesh.area[j] * glm::dot(ref.radiosity_se[j], ref.radiosity_se[j]);
        b2 += mesh.area[j] * glm::dot(ref.radiosity[j], ref.radiosity[j]);
      }
      truth_err = std::sqrt(se2 / b2);
      truth_runs = 0;
      std::fprintf(stderr, "truth from %s, its own relative RMS error ~%.4f\n", reference.c_str(), truth_err);
    }
    std::vector<glm::dvec3> total(mesh.size(), glm::dvec3(0.0));
    std::vector<std::vector<glm::vec3>> truths;
    for (int r = 0; r < truth_runs; ++r) {
      Solver s(mesh, *engine, {.seed = 1000 + static_cast<uint64_t>(r)});
      for (uint64_t k = 0; k < truth_bundles; ++k) s.step(k);
      truths.push_back(s.estimate());
      for (std::size_t j = 0; j < mesh.size(); ++j) total[j] += s.sum()[j];
      std::fprintf(stderr, "truth run %d done\n", r);
    }
    if (truth_runs > 0)
      for (std::size_t j = 0; j < mesh.size(); ++j)
        truth[j] = glm::vec3(total[j] / static_cast<double>(truth_bundles * truth_runs));
    // Its error: each run's squared difference from the mean is (R - 1) / R of a run's
    // variance, so Var(truth) = Var(run) / R = mean_r |run_r - truth|^2 / (R - 1).
    if (truth_runs >= 2) {
      for (const auto& t : truths) truth_err += std::pow(relative_rms(mesh, t, truth), 2) / truth_runs;
      truth_err = std::sqrt(truth_err / (truth_runs - 1));
    }
    if (truth_runs > 0) {
      std::fprintf(stderr, "truth: %d x %llu bundles, its own relative RMS error ~%.4f\n", truth_runs,
                   static_cast<unsigned long long>(truth_bundles), truth_err);
      if (!truth_file.empty()) {
        std::FILE* f = std::fopen(truth_file.c_str(), "wb");
        if (!f) fail("cannot write {}", truth_file);
        std::fwrite(&truth_err, sizeof truth_err, 1, f);
        std::fwrite(truth.data(), sizeof(glm::vec3), truth.size(), f);
        std::fclose(f);
      }
    }

    std::printf("patches,mode,seed,bundles,relative_rms,area_mean\n");
    // err[mode][checkpoint][seed]
    std::vector<std::vector<std::vector<double>>> err(2, std::vector<std::vector<double>>(checkpoints.size()));
    std::vector<std::vector<double>> means(2);
    for (int sd = 0; sd < seeds; ++sd) {
      for (int mode = 0; mode < 2; ++mode) {
        Directions d = mode == 0 ? Directions::random : Directions::stratified;
        SolverOptions so{.seed = static_cast<uint64_t>(first_seed + sd), .directions = d, .interleave = interleave,
                         .strata_side = side};
        so.shots_per_bundle = shots;
        Solver s(mesh, *engine, so, shot_engine.get());
        std::size_t next = 0;
        for (uint64_t k = 0; next < checkpoints.size(); ++k) {
          s.step(k);
          if (s.bundles() == checkpoints[next]) {
            auto est = s.estimate();
            double e = relative_rms(mesh, est, truth), m = area_mean(mesh, est);
            err[mode][next].push_back(e);
            std::printf("%zu,%s,%d,%llu,%.6f,%.6f\n", mesh.size(), to_string(d), first_seed + sd,
                        static_cast<unsigned long long>(checkpoints[next]), e, m);
            std::fflush(stdout);
            if (next + 1 == checkpoints.size()) means[mode].push_back(m);
            ++next;
          }
        }
      }
    }
    std::fprintf(stderr, "bundles  random  stratified  ratio(rms over seeds)  paired ratios min..max  "
                         "(truth error %.4f subtracted: random, stratified, ratio)\n", truth_err);
    for (std::size_t c = 0; c < checkpoints.size(); ++c) {
      double r2 = 0, s2 = 0, lo = 1e9, hi = 0;
      for (int sd = 0; sd < seeds; ++sd) {
        r2 += err[0][c][sd] * err[0][c][sd] / seeds;
        s2 += err[1][c][sd] * err[1][c][sd] / seeds;
        double q = err[1][c][sd] / err[0][c][sd];
        lo = std::min(lo, q);
        hi = std::max(hi, q);
      }
      double t2 = truth_err * truth_err;
      double rc = std::sqrt(std::max(0.0, r2 - t2)), sc = std::sqrt(std::max(0.0, s2 - t2));
      std::fprintf(stderr, "%6llu  %.4f  %.4f  %.3f  %.3f..%.3f  (%.4f %.4f %.3f)\n",
                   static_cast<unsigned long long>(checkpoints[c]), std::sqrt(r2), std::sqrt(s2),
                   std::sqrt(s2 / r2), lo, hi, rc, sc, sc / rc);
    }
    for (int mode = 0; mode < 2; ++mode) {
      double m = 0, v = 0;
      for (double x : means[mode]) m += x / means[mode].size();
      for (double x : means[mode]) v += (x - m) * (x - m) / (means[mode].size() - 1);
      std::fprintf(stderr, "%s: area mean at %llu bundles %.5f +- %.5f (truth %.5f)\n", mode ? "stratified" : "random",
                   static_cast<unsigned long long>(checkpoints.back()), m, std::sqrt(v / means[mode].size()),
                   area_mean(mesh, truth));
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_directions: %s\n", e.what());
    return 1;
  }
}
