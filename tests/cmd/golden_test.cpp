// sirad tests: the outputs of a fixed set of runs, bit for bit. Each run below has fixed seeds
// and settings whose result does not depend on timing (one node; sync mode with balance off,
// where every node gets the same grants whatever its speed; virtual time with a fixed bundle
// time; a checkpoint resumed by one node), so its outputs are a function of the code alone.
// Their digests are in tests/data/golden/digests.txt; a change that alters any output (a
// radiosity value, an EXR attribute, a status counter, a line of the timeline) fails here.
// A deliberate change of results re-records them:
//   SIRAD_GOLDEN_RECORD=1 build/tests/sirad_tests --gtest_filter='Golden.*'
// Left out by design, since their outputs differ from run to run: async runs of two or more
// real nodes (which node runs which bundle depends on their speeds) and the average rule on
// two or more real nodes (the others' state a node absorbs depends on the order the reports
// of an exchange round arrive in); the emulated runs cover both in virtual time.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <xxhash.h>

#include "cluster/status.h"
#include "tests/exr_content.h"
#include "tests/png_util.h"
#include "tests/process_util.h"
#include "tests/test_folder.h"

namespace fs = std::filesystem;
using sirad::test::Child;
using sirad::test::slurp;

namespace {

const fs::path kDigests = fs::path(SIRAD_SOURCE_DIR) / "tests/data/golden/digests.txt";

std::string hex(const std::string& bytes) { return fmt::format("{:016x}", XXH64(bytes.data(), bytes.size(), 0)); }

// A --status-json file less what depends on the clock or the machine (times, rates, device,
// and node names, which follow the order the nodes happened to say HELLO in).
std::string status_content(const fs::path& path) {
  sirad::cluster::Status s = sirad::cluster::read_status(path.string());
  std::string out = fmt::format("bundles {}/{} error {} exchanges {} bytes {} {} I {} S {} {} {} target {} ended '{}'",
                                s.bundles_done, s.bundles, s.error_estimate, s.exchanges, s.bytes_in, s.bytes_out,
                                s.exchange_every, s.exchange_fraction, s.mode, s.topology, s.target_error, s.ended_by);
  for (const auto& n : s.nodes) out += fmt::format("\nnode {} {} {} '{}'", n.state, n.bundles, n.exchanges, n.why);
  return out;
}

// A --ledger CSV less its name column (the same reason).
std::string ledger_content(const fs::path& path) {
  std::string csv = slurp(path), out;
  std::size_t at = 0;
  while (at < csv.size()) {
    std::size_t end = csv.find('\n', at);
    if (end == std::string::npos) end = csv.size();
    std::string line = csv.substr(at, end - at);
    std::size_t a = line.find(','), b = line.rfind(',');
    b = line.rfind(',', b - 1);
    out += line.substr(0, a) + line.substr(b) + "\n";
    at = end + 1;
  }
  return out;
}

std::string digest_of(const fs::path& file, bool pixels = true) {
  const std::string ext = file.extension().string();
  if (ext == ".exr") return hex(sirad::test::exr_content(file, pixels));
  if (file.filename().string().find("status") != std::string::npos) return hex(status_content(file));
  if (file.filename().string().find("ledger") != std::string::npos) return hex(ledger_content(file));
  return hex(slurp(file));
}

class Golden : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = sirad::test::fresh_test_folder("sirad_golden");
    // The band count of the transfer pass orders float sums (engine/bundle_cl.h): fixed, so the
    // digests do not depend on the machine's core count.
    ::setenv("SIRAD_BANDS", "4", 1);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  // Runs `args` (a binary and its flags) to exit status 0.
  void run(std::vector<std::string> args, const std::string& log) {
    Child c(std::move(args), dir_ / log);
    ASSERT_EQ(c.wait(sirad::test::kHangS), 0) << slurp(dir_ / log);
  }

  // The coordinator `args` (its flags after the scene) with `nodes` node processes over
  // loopback TCP; the coordinator waits for all of them (--min-nodes) where the run is new.
  void run_tcp(std::vector<std::string> args, int nodes, const std::string& name) {
    std::vector<std::string> coord = {SIRAD_COORDINATOR_BINARY, "cornell", "--listen", "tcp://127.0.0.1:*", "--insecure", "-q",
                                      "--endpoint-file", (dir_ / (name + ".endpoint")).string(), "--timeout", sirad::test::kHangTimeout};
    coord.insert(coord.end(), args.begin(), args.end());
    Child coordinator(coord, dir_ / (name + ".coordinator.log"));
    // An event, not a clock: the endpoint file appears once the socket is bound.
    ASSERT_TRUE(sirad::test::wait_for_file(dir_ / (name + ".endpoint"), coordinator))
        << slurp(dir_ / (name + ".coordinator.log"));
    std::vector<std::unique_ptr<Child>> node;
    for (int i = 0; i < nodes; ++i)
      node.push_back(std::make_unique<Child>(
          std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", slurp(dir_ / (name + ".endpoint")), "--insecure", "--name",
                                   fmt::format("{}-{}", name, i)},
          dir_ / fmt::format("{}.node{}.log", name, i)));
    ASSERT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir_ / (name + ".coordinator.log"));
    for (auto& n : node) {
      n->terminate();
      EXPECT_EQ(n->wait(sirad::test::kHangS), 0);
    }
  }

  // Every output of run `name` (files NAME.*, NAME-*.csv and NAME-status.json) against the
  // recorded digests, or into them with SIRAD_GOLDEN_RECORD. With `traced`, the run's images
  // come from rays traced by Embree, whose arithmetic follows the CPU (it picks SSE, AVX2 or
  // AVX-512 code as the machine allows): their pixels are held against recorded images within
  // the bounds of expect_traced_alike, their attributes by digest.
  void check(const std::string& name, bool traced = false) {
    std::map<std::string, std::string> got;
    std::vector<fs::path> images;
    std::size_t outputs = 0;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string f = e.path().filename().string();
      const std::string ext = e.path().extension().string();
      if (f.rfind(name + ".", 0) != 0 && f.rfind(name + "-", 0) != 0) continue;
      if (ext != ".exr" && ext != ".png" && ext != ".ply" && ext != ".glb" && ext != ".csv" && ext != ".json") continue;
      ++outputs;
      const bool image = traced && (ext == ".exr" || ext == ".png");
      if (image) images.push_back(e.path());
      if (ext != ".png" || !image) got[f] = digest_of(e.path(), !image);
    }
    for (const fs::path& image : images) {
      const fs::path recorded = kDigests.parent_path() / image.filename();
      if (std::getenv("SIRAD_GOLDEN_RECORD")) fs::copy_file(image, recorded, fs::copy_options::overwrite_existing);
      else expect_traced_alike(image, recorded);
    }
    ASSERT_GE(outputs, 4u) << name << ": its outputs are missing";
    std::map<std::string, std::string> recorded;
    {
      std::istringstream in(slurp(kDigests));
      std::string file, digest;
      while (in >> file >> digest) recorded[file] = digest;
    }
    if (std::getenv("SIRAD_GOLDEN_RECORD")) {
      for (auto it = recorded.begin(); it != recorded.end();)
        it = it->first.rfind(name + ".", 0) == 0 || it->first.rfind(name + "-", 0) == 0 ? recorded.erase(it) : std::next(it);
      for (const auto& [f, d] : got) recorded[f] = d;
      std::string text;
      for (const auto& [f, d] : recorded) text += f + " " + d + "\n";
      fs::create_directories(kDigests.parent_path());
      std::ofstream(kDigests) << text;
      return;
    }
    for (const auto& [f, d] : got) {
      auto it = recorded.find(f);
      ASSERT_NE(it, recorded.end()) << f << ": no recorded digest";
      EXPECT_EQ(d, it->second) << f << " differs from the recorded output";
    }
    for (const auto& [f, d] : recorded) {
      if (f.rfind(name + ".", 0) == 0 || f.rfind(name + "-", 0) == 0) {
        EXPECT_TRUE(got.count(f)) << f << ": not written";
      }
    }
  }

  // An image of traced rays (`got`) against the one recorded on another machine (`want`), as
  // a CPU's arithmetic can move it. The same code on another instruction set rounds a ray's
  // hit point and distance differently in the last bits, so a sample's value (radiosity
  // interpolated at the hit, its cosines) moves by some float ulps: every channel within
  // kUlpShare relative of the recorded one. A sample whose ray grazes an edge may meet the face
  // on its other side, or pass it: its pixel then moves by that sample's share, which nothing
  // smaller than the pixel bounds; at most kGrazedShare of the pixels may do so. kUlpShare is
  // about 80 float ulps, kGrazedShare a handful of pixels' samples at edges. A PNG, 8 bits of
  // the same values: within 1 where the EXR is within kUlpShare.
  void expect_traced_alike(const fs::path& got, const fs::path& want) {
    constexpr double kUlpShare = 1e-5, kGrazedShare = 0.02;
    ASSERT_TRUE(fs::exists(want)) << want << ": no recorded image";
    std::vector<std::vector<float>> a, b;  // per channel
    if (got.extension() == ".exr") {
      const auto ca = sirad::test::exr_channels(got), cb = sirad::test::exr_channels(want);
      ASSERT_EQ(ca.size(), cb.size()) << got;
      for (const auto& [c, v] : ca) {
        ASSERT_TRUE(cb.count(c)) << got << ": channel " << c;
        a.push_back(v);
        b.push_back(cb.at(c));
      }
    } else {
      int wa = 0, ha = 0, wb = 0, hb = 0;
      const std::vector<unsigned char> pa = sirad::test::read_png(got.string(), wa, ha), pb = sirad::test::read_png(want.string(), wb, hb);
      ASSERT_EQ(std::tie(wa, ha), std::tie(wb, hb)) << got;
      for (int c = 0; c < 3; ++c) {
        a.emplace_back();
        b.emplace_back();
        for (std::size_t k = c; k < pa.size(); k += 3) {
          a.back().push_back(pa[k]);
          b.back().push_back(pb[k]);
        }
      }
    }
    const std::size_t pixels = a.front().size();
    std::size_t grazed = 0;
    double worst = 0.0;  // the largest relative difference within rounding
    for (std::size_t k = 0; k < pixels; ++k) {
      bool moved = false;
      for (std::size_t c = 0; c < a.size(); ++c) {
        ASSERT_EQ(a[c].size(), pixels);
        const double x = a[c][k], y = b[c][k];
        const double close = got.extension() == ".exr" ? kUlpShare * std::max(std::abs(x), std::abs(y)) : 1.0;
        if (std::abs(x - y) > close) moved = true;
        else if (x != y) worst = std::max(worst, std::abs(x - y) / std::max(std::abs(x), std::abs(y)));
      }
      grazed += moved;
    }
    std::printf("%s: %zu of %zu pixels beyond the arithmetic's rounding; within it, %.2g relative at most\n", got.filename().c_str(),
                grazed, pixels, worst);
    EXPECT_LE(static_cast<double>(grazed), kGrazedShare * pixels) << got << ": pixels moved beyond rounding";
  }

  std::string out(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

const std::vector<std::string> kSmall = {"--patches", "300", "--width", "24", "--height", "24", "-q"};

std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TEST_F(Golden, SingleNode) {
  run(with({SIRAD_BINARY, "render", "cornell", "--bundles", "48", "--seed", "5", "--out", out("single")}, kSmall), "single.log");
  check("single");
}

// The final gather (render/gather.h) of the single-node run above: its EXR passes and PNG.
TEST_F(Golden, SingleNodeFinalGather) {
  run(with({SIRAD_BINARY, "render", "cornell", "--bundles", "48", "--seed", "5", "--final-gather", "4", "--out", out("gather")}, kSmall),
      "gather.log");
  check("gather", true);
}

TEST_F(Golden, SingleNodeAverageRulePlainEstimator) {
  run(with({SIRAD_BINARY, "render", "cornell", "--bundles", "40", "--seed", "6", "--rule", "average", "--control-variate", "off",
            "--shots-per-bundle", "0", "--out", out("plain")},
           kSmall),
      "plain.log");
  check("plain");
}

TEST_F(Golden, EmbeddedOneNodeAsync) {
  run(with({SIRAD_BINARY, "render", "cornell", "--nodes", "1", "--bundles", "64", "--seed", "7", "--exchange-every", "8",
            "--status-json", out("async1-status.json"), "--out", out("async1")},
           kSmall),
      "async1.log");
  check("async1");
}

TEST_F(Golden, EmbeddedTwoNodesSync) {
  run(with({SIRAD_BINARY, "render", "cornell", "--nodes", "2", "--mode", "sync", "--balance", "off", "--bundles", "96", "--seed",
            "8", "--exchange-every", "8", "--status-json", out("sync2-status.json"), "--out", out("sync2")},
           kSmall),
      "sync2.log");
  check("sync2");
}

TEST_F(Golden, EmbeddedThreeNodesSyncRing) {
  run(with({SIRAD_BINARY, "render", "cornell", "--nodes", "3", "--mode", "sync", "--balance", "off", "--topology", "ring", "--exchange-every", "8", "--exchange-fraction", "0.5", "--chunks", "4", "--bundles", "96",
            "--seed", "9", "--status-json", out("ring3-status.json"), "--out", out("ring3")},
           kSmall),
      "ring3.log");
  check("ring3");
}

TEST_F(Golden, EmulatedHetero16) {
  run(with({SIRAD_BINARY, "emulate", "cornell", "--profile", SIRAD_SOURCE_DIR "/deploy/profiles/hetero-16.yaml", "--bundle-ms",
            "2", "--bundles", "512", "--seed", "10", "--exchange-every", "8", "--nodes-csv", out("hetero16-nodes.csv"),
            "--timeline", out("hetero16-timeline.csv"), "--out", out("hetero16")},
           kSmall),
      "hetero16.log");
  check("hetero16");
}

TEST_F(Golden, EmulatedFourNodesAsyncAuto) {
  run(with({SIRAD_BINARY, "emulate", "cornell", "--nodes", "4", "--bundle-ms", "3", "--bundles", "256", "--seed", "11",
            "--exchange-every", "auto", "--target-error", "0.2", "--nodes-csv", out("auto4-nodes.csv"), "--timeline",
            out("auto4-timeline.csv"), "--out", out("auto4")},
           kSmall),
      "auto4.log");
  check("auto4");
}

TEST_F(Golden, CoordinatorWithTwoNodeProcesses) {
  run_tcp(with({"--min-nodes", "2", "--mode", "sync", "--balance", "off", "--bundles", "96", "--seed", "12", "--exchange-every",
                "8", "--status-json", out("tcp2-status.json"), "--ledger", out("tcp2-ledger.csv"), "--out", out("tcp2")},
               {"--patches", "300", "--width", "24", "--height", "24"}),
          2, "tcp2");
  check("tcp2");
}

// A farm job is an ordinary run: the run above, submitted to a farm (sirad-coordinator --serve)
// with the same flags and taken by two node processes, writes the same outputs bit for bit as
// the lone coordinator did (its recorded digests; the ledger less its names).
TEST_F(Golden, AFarmJobIsTheSameRunAsALoneCoordinators) {
  const fs::path farm = dir_ / "farm";
  Child server({SIRAD_COORDINATOR_BINARY, "--serve", farm.string(), "--listen", "tcp://127.0.0.1:*", "--insecure", "--endpoint-file",
                out("farm.endpoint"), "--http", "127.0.0.1:0"},
               dir_ / "farm.log");
  ASSERT_TRUE(sirad::test::wait_for_file(dir_ / "farm.endpoint", server)) << slurp(dir_ / "farm.log");
  Child submit({SIRAD_BINARY, "submit", "cornell", "--farm", farm.string(), "--name", "tcp2", "--min-nodes", "2", "--mode", "sync",
                "--balance", "off", "--bundles", "96", "--seed", "12", "--exchange-every", "8", "--patches", "300", "--width", "24",
                "--height", "24"},
               dir_ / "submit.log");
  ASSERT_EQ(submit.wait(sirad::test::kHangS), 0) << slurp(dir_ / "submit.log");
  std::vector<std::unique_ptr<Child>> nodes;
  for (int i = 0; i < 2; ++i)
    nodes.push_back(std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", slurp(dir_ / "farm.endpoint"), "--insecure", "--name",
                                 fmt::format("farm-{}", i)},
        dir_ / fmt::format("farm.node{}.log", i)));
  const fs::path job = farm / "jobs" / "1";
  ASSERT_TRUE(sirad::test::wait_until([&] { return fs::exists(job / "summary.txt"); })) << slurp(dir_ / "farm.log");
  std::map<std::string, std::string> recorded;
  {
    std::istringstream in(slurp(kDigests));
    std::string file, digest;
    while (in >> file >> digest) recorded[file] = digest;
  }
  for (const char* f : {"tcp2.exr", "tcp2.png", "tcp2.ply", "tcp2.glb"}) EXPECT_EQ(digest_of(job / f), recorded.at(f)) << f;
  EXPECT_EQ(hex(ledger_content(job / "ledger.csv")), recorded.at("tcp2-ledger.csv"));
  for (auto& n : nodes) n->terminate();
  server.terminate();
  EXPECT_EQ(server.wait(sirad::test::kHangS), 0) << slurp(dir_ / "farm.log");
}

// tests/data/golden/resume.ckpt: a run of 4096 bundles of the Cornell box (300 patches, seed
// 13, exchange every 8) checkpointed after 616 of them by one node, resumed here by another.
TEST_F(Golden, ResumedCheckpoint) {
  fs::copy_file(fs::path(SIRAD_SOURCE_DIR) / "tests/data/golden/resume.ckpt", dir_ / "resume.ckpt");
  run_tcp({"--resume", out("resume.ckpt"), "--width", "24", "--height", "24", "--status-json",
           out("resume-status.json"), "--ledger", out("resume-ledger.csv"), "--out", out("resume")},
          1, "resume");
  check("resume");
}

}  // namespace
