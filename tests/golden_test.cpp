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
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <xxhash.h>

#include "cluster/status.h"
#include "tests/exr_content.h"
#include "tests/process_util.h"

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

std::string digest_of(const fs::path& file) {
  const std::string ext = file.extension().string();
  if (ext == ".exr") return hex(sirad::test::exr_content(file));
  if (file.filename().string().find("status") != std::string::npos) return hex(status_content(file));
  if (file.filename().string().find("ledger") != std::string::npos) return hex(ledger_content(file));
  return hex(slurp(file));
}

class Golden : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("sirad_golden_{}_{}", ::getpid(),
                                                    ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // The band count of the transfer pass orders float sums (core/bundle_cl.h): fixed, so the
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
  // recorded digests, or into them with SIRAD_GOLDEN_RECORD.
  void check(const std::string& name) {
    std::map<std::string, std::string> got;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string f = e.path().filename().string();
      const std::string ext = e.path().extension().string();
      if (f.rfind(name + ".", 0) != 0 && f.rfind(name + "-", 0) != 0) continue;
      if (ext != ".exr" && ext != ".png" && ext != ".ply" && ext != ".glb" && ext != ".csv" && ext != ".json") continue;
      got[f] = digest_of(e.path());
    }
    ASSERT_GE(got.size(), 4u) << name << ": its outputs are missing";
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

// The final gather (core/gather.h) of the single-node run above: its EXR passes and PNG.
TEST_F(Golden, SingleNodeFinalGather) {
  run(with({SIRAD_BINARY, "render", "cornell", "--bundles", "48", "--seed", "5", "--final-gather", "4", "--out", out("gather")}, kSmall),
      "gather.log");
  check("gather");
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
// 13, exchange every 8) checkpointed after 588 of them by one node, resumed here by another.
TEST_F(Golden, ResumedCheckpoint) {
  fs::copy_file(fs::path(SIRAD_SOURCE_DIR) / "tests/data/golden/resume.ckpt", dir_ / "resume.ckpt");
  run_tcp({"--resume", out("resume.ckpt"), "--width", "24", "--height", "24", "--status-json",
           out("resume-status.json"), "--ledger", out("resume-ledger.csv"), "--out", out("resume")},
          1, "resume");
  check("resume");
}

}  // namespace
