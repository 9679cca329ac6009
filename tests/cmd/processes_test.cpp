// sirad tests: the cluster as separate processes: one sirad-coordinator and three sirad-node
// processes over loopback TCP on a port the system picks (never a fixed one).
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <fmt/format.h>
#include <glm/vec3.hpp>
#include <gtest/gtest.h>

#include "cluster/status.h"
#include "engine/bundle_cl.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/solver.h"
#include "tests/exr_content.h"
#include "tests/png_util.h"
#include "tests/process_util.h"
#include "tests/run_files.h"

namespace fs = std::filesystem;
using sirad::test::bundles_done;
using sirad::test::Child;
using sirad::test::expect_every_index_once;
using sirad::test::insecure_nodes;
using sirad::test::LedgerRow;
using sirad::test::ply_radiosity;
using sirad::test::read_ledger;
using sirad::test::run_processes;
using sirad::test::slurp;
using sirad::test::status_nodes;

namespace {

// `sirad keygen NAME` in `dir`; returns the allow-list line it prints.
std::string keygen(const fs::path& dir, const std::string& name) {
  std::string line = sirad::test::keygen(SIRAD_BINARY, dir, name);
  EXPECT_FALSE(line.empty()) << slurp(dir / (name + ".keygen.log"));
  return line;
}

// Coordinator plus 3 node processes over loopback TCP with CURVE (keys from `sirad keygen`, the
// nodes' public keys in the allow list): the run completes with every bundle done once (the
// per-node counts add up to K, the ledger refuses repeats), the outputs are written, the nodes
// stop cleanly on SIGTERM, and the furnace's mean is 2 within 4 standard deviations of a
// 512-bundle chain average (0.0097 * sqrt(1024 / 512) * 4 = 0.055).
TEST(Processes, CoordinatorAndThreeNodesOverTcp) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_proc_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  keygen(dir, "coordinator");
  {
    std::ofstream allow(dir / "allow");
    for (int i = 0; i < 3; ++i) allow << keygen(dir, fmt::format("p{}", i)) << "\n";
  }
  Child coordinator({SIRAD_COORDINATOR_BINARY, "furnace", "--listen", "tcp://127.0.0.1:*", "--curve-secret",
                     (dir / "coordinator.key_secret").string(), "--allow", (dir / "allow").string(), "--endpoint-file",
                     (dir / "endpoint").string(), "--bundles", "512", "--patches", "300", "--min-nodes", "3",
                     "--exchange-every", "16", "--out", (dir / "furnace").string(), "--width", "16", "--height", "16",
                     "--timeout", sirad::test::kHangTimeout},
                    dir / "coordinator.log");
  ASSERT_TRUE(coordinator.started());
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  std::string endpoint = slurp(dir / "endpoint");
  ASSERT_EQ(endpoint.rfind("tcp://127.0.0.1:", 0), 0u) << endpoint;
  std::vector<std::unique_ptr<Child>> nodes;
  for (int i = 0; i < 3; ++i)
    nodes.push_back(std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--name", fmt::format("p{}", i), "--curve-secret",
                                 (dir / fmt::format("p{}.key_secret", i)).string(), "--server-key",
                                 (dir / "coordinator.key").string()},
        dir / fmt::format("node{}.log", i)));
  ASSERT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator.log");
  std::string log = slurp(dir / "coordinator.log");
  uint64_t total = 0;
  for (int i = 0; i < 3; ++i) {
    auto at = log.find(fmt::format("node p{}: ", i));
    ASSERT_NE(at, std::string::npos) << log;
    total += std::stoull(log.substr(at + 9));
  }
  EXPECT_EQ(total, 512u) << log;
  for (const char* ext : {".exr", ".png", ".ply"}) EXPECT_TRUE(fs::exists(dir / (std::string("furnace") + ext)));
  std::vector<glm::vec3> radiosity = ply_radiosity(dir / "furnace.ply");
  double sum = 0.0;
  for (const auto& r : radiosity) sum += r.x;
  const auto faces = radiosity.size();
  double mean = sum / static_cast<double>(faces);  // the furnace's patches have nearly equal areas
  std::printf("3 node processes, furnace: mean radiosity %.4f\n", mean);
  EXPECT_NEAR(mean, 2.0, 0.055);
  for (auto& n : nodes) {
    n->terminate();
    EXPECT_EQ(n->wait(sirad::test::kHangS), 0);
  }
  fs::remove_all(dir);
}

// The embedded default and the TCP cluster are the same code: with one node, `sirad render
// --nodes 1` (inproc, one process) and sirad-coordinator + one sirad-node process over loopback
// TCP run the same bundles in the same order on the same chain, so the PLY files (radiosity
// per patch, written deterministically) are identical byte for byte.
TEST(Processes, EmbeddedDefaultEqualsTcpClusterBitForBit) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_same_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::vector<std::string> run = {"--bundles", "200", "--patches", "400", "--seed", "9", "--exchange-every", "8",
                                        "--width", "16", "--height", "16"};
  std::vector<std::string> embedded = {SIRAD_BINARY, "render", "cornell", "--nodes", "1", "-q", "--out",
                                       (dir / "embedded").string()};
  embedded.insert(embedded.end(), run.begin(), run.end());
  Child e(embedded, dir / "embedded.log");
  ASSERT_EQ(e.wait(sirad::test::kHangS), 0) << slurp(dir / "embedded.log");
  std::vector<std::string> coord = {SIRAD_COORDINATOR_BINARY, "cornell", "--listen", "tcp://127.0.0.1:*", "--insecure", "-q",
                                    "--endpoint-file", (dir / "endpoint").string(), "--out", (dir / "tcp").string(),
                                    "--timeout", sirad::test::kHangTimeout};
  coord.insert(coord.end(), run.begin(), run.end());
  Child coordinator(coord, dir / "coordinator.log");
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  Child node({SIRAD_NODE_BINARY, "--connect", slurp(dir / "endpoint"), "--insecure", "--name", "tcp-node"}, dir / "node.log");
  ASSERT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator.log");
  EXPECT_NE(slurp(dir / "coordinator.log").find("WARNING: --insecure"), std::string::npos) << "it says so on start";
  std::string a = slurp(dir / "embedded.ply"), b = slurp(dir / "tcp.ply");
  ASSERT_GT(a.size(), 1000u);
  EXPECT_TRUE(a == b) << "the embedded default and the TCP cluster differ";
  node.terminate();
  EXPECT_EQ(node.wait(sirad::test::kHangS), 0);
  fs::remove_all(dir);
}

// The Cornell box's agreement test (see CornellClusterAgreesWithSingleNodeRuns): the cluster's
// mean D^2 against 4 single-node runs of the same `bundles` (300 patches, plain estimator)
// matches theirs among themselves within a factor 1.6, and its scene mean is within 4 sd.
void expect_agrees_with_single_runs(const std::vector<glm::vec3>& cluster, uint64_t bundles) {
  sirad::PatchMesh mesh = sirad::mesh_scene(sirad::builtin_cornell(), {.target_patches = 300});
  ASSERT_EQ(cluster.size(), mesh.size());
  auto engine = sirad::make_cl_engine(mesh);
  std::vector<std::vector<glm::vec3>> single;
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    sirad::Solver solver(mesh, *engine, {.seed = seed});
    for (uint64_t k = 0; k < bundles; ++k) solver.step(k);
    single.push_back(solver.estimate());
  }
  auto d2 = [&](const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
    double d = sirad::relative_rms(mesh, a, b);
    return d * d;
  };
  double among = 0, against = 0, m = 0, mm = 0;
  for (int i = 0; i < 4; ++i) {
    against += d2(cluster, single[i]) / 4;
    for (int j = i + 1; j < 4; ++j) among += d2(single[i], single[j]) / 6;
    double mean = sirad::area_mean(mesh, single[i]);
    m += mean / 4;
    mm += mean * mean / 4;
  }
  double sd = std::sqrt((mm - m * m) * 4 / 3);
  double cluster_mean = sirad::area_mean(mesh, cluster);
  std::printf("Cornell: D^2 cluster vs single %.4f, single vs single %.4f (ratio %.3f); scene mean %.5f vs %.5f (sd %.2g)\n",
              against, among, against / among, cluster_mean, m, sd);
  EXPECT_LT(against / among, 1.6);
  EXPECT_GT(against / among, 1 / 1.6);
  EXPECT_LE(std::abs(cluster_mean - m), 4 * sd * std::sqrt(1.25));
}

// On the Cornell box, 3 node processes over TCP agree with single-node runs of the same total
// bundles (K = 512, 300 patches). With independent estimates of the same expectation, the
// squared relative RMS difference D^2 of any two has expectation 2 Var (metrics.h), so the
// cluster's mean D^2 against 4 single runs matches the single runs' mean D^2 among themselves.
// Noise: log D^2 of one pair has sd about 0.125 here (solver_test's convergence slope, sd 0.032
// over a log range of ln 16, measured with 3 pooled pairs), so the log of the ratio of the two
// pooled means has sd about 0.125 (4 and 6 pairs, correlated through the shared runs): we allow
// a factor 1.6 (3.8 sd) each way. A bias between cluster and single node adds its square to the
// cluster's D^2; a cluster that duplicated or dropped bundles has a different variance. The
// scene mean (area-weighted, red) is checked for bias against the single runs' spread: within
// 4 sd of one run, sqrt(1 + 1/4) for the mean of 4.
TEST(Processes, CornellClusterAgreesWithSingleNodeRuns) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_cornell_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  // The plain estimator on both sides (the single runs below have no first shot).
  ASSERT_EQ(run_processes(dir, 3, {"cornell", "--bundles", "512", "--patches", "300", "--seed", "99", "--exchange-every",
                                   "16", "--shots-per-bundle", "0", "--out", (dir / "cluster").string(), "--width", "16",
                                   "--height", "16"}),
            0)
      << slurp(dir / "coordinator.log");
  expect_agrees_with_single_runs(ply_radiosity(dir / "cluster.ply"), 512);
  fs::remove_all(dir);
}

struct KillRun {
  int status = -1;
  std::string log;
  std::vector<LedgerRow> ledger;
  uint64_t done_at_kill = 0;
};

using sirad::test::wait_until;

// A coordinator and 3 node processes (p0, p1, p2) over loopback TCP; node p1 gets SIGKILL in
// the middle of the run. No step races the clock: the run is held open until each event has
// happened.
//   1. p0 and p2 join and wait (the run needs 3 nodes), then are stopped (SIGSTOP);
//   2. p1 joins, the run starts and grants go to all three; p0's and p2's stay outstanding while
//      they are stopped (heartbeats every 250 ms with a liveness of 100 keep them alive 25 s),
//      so the run cannot end; p1 works alone until the status shows bundles of its own;
//   3. p1 is killed; the coordinator declares it dead (its next heartbeat cannot be sent);
//   4. with `restart`, a new p1 process starts (the same name, a new routing id: it joins as a
//      new node) and works alone until the status shows its bundles;
//   5. p0 and p2 continue and the run finishes.
KillRun run_with_kill(const fs::path& dir, std::vector<std::string> run_args, uint64_t bundles, bool restart) {
  const fs::path status = dir / "status.json";
  std::vector<std::string> args = {SIRAD_COORDINATOR_BINARY, "--listen", "tcp://127.0.0.1:*", "--insecure",
                                   "--endpoint-file", (dir / "endpoint").string(), "--min-nodes", "3", "--timeout", sirad::test::kHangTimeout,
                                   "--heartbeat-ms", "250", "--liveness", "100", "--status-json", status.string(),
                                   "--ledger", (dir / "ledger.csv").string(), "--bundles", std::to_string(bundles), "-q"};
  args.insert(args.end(), run_args.begin(), run_args.end());
  KillRun out;
  Child coordinator(args, dir / "coordinator.log");
  EXPECT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  std::string endpoint = slurp(dir / "endpoint");
  auto node = [&](int i, const std::string& log) {
    return std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--insecure", "--name", fmt::format("p{}", i)},
        dir / log);
  };
  // Whether the status lists `count` nodes named `name` and the last of them is in one of `states`
  // (with bundles, when `working`).
  auto shows = [&](const std::string& name, std::size_t count, std::set<std::string> states, bool working) {
    std::vector<sirad::cluster::Status::Node> found;
    for (const auto& n : status_nodes(status))
      if (n.name == name) found.push_back(n);
    return found.size() == count && states.count(found.back().state) && (!working || found.back().bundles > 0);
  };
  std::vector<std::unique_ptr<Child>> nodes(3);
  nodes[0] = node(0, "node0.log");
  nodes[2] = node(2, "node2.log");
  EXPECT_TRUE(wait_until([&] { return shows("p0", 1, {"waiting"}, false) && shows("p2", 1, {"waiting"}, false); }, sirad::test::kHangS))
      << "p0 and p2 never joined: " << slurp(dir / "coordinator.log");
  nodes[0]->pause();
  nodes[2]->pause();
  nodes[1] = node(1, "node1.log");
  EXPECT_TRUE(wait_until([&] { return shows("p1", 1, {"working", "waiting"}, true); }, sirad::test::kHangS)) << "p1 never ran a bundle";
  nodes[1]->kill9();
  out.done_at_kill = bundles_done(status);
  EXPECT_TRUE(wait_until([&] { return slurp(dir / "coordinator.log").find("p1: declared dead") != std::string::npos; }, sirad::test::kHangS))
      << "p1 was never declared dead";
  if (restart) {
    nodes.push_back(node(1, "node1-restarted.log"));
    EXPECT_TRUE(wait_until([&] { return shows("p1", 2, {"working", "waiting"}, true); }, sirad::test::kHangS))
        << "the new p1 never ran a bundle";
  }
  nodes[0]->resume();
  nodes[2]->resume();
  out.status = coordinator.wait(sirad::test::kHangS);
  out.log = slurp(dir / "coordinator.log");
  for (auto& n : nodes) n->terminate();
  if (fs::exists(dir / "ledger.csv")) out.ledger = read_ledger(dir / "ledger.csv");
  return out;
}

// `sirad image` of dir/run.ply (spp samples, `view` its size flags) into dir/one: its EXR must
// be the cluster's dir/run.exr bit for bit, every channel.
void expect_the_image_of_one_machine(const fs::path& dir, const std::string& spp, const std::vector<std::string>& view) {
  std::vector<std::string> image = {SIRAD_BINARY, "image", (dir / "run.ply").string(), "--spp", spp, "--out",
                                    (dir / "one").string(), "-q"};
  image.insert(image.end(), view.begin(), view.end());
  Child one(image, dir / "one.log");
  ASSERT_EQ(one.wait(sirad::test::kHangS), 0) << slurp(dir / "one.log");
  const auto tiled = sirad::test::exr_channels(dir / "run.exr"), whole = sirad::test::exr_channels(dir / "one.exr");
  ASSERT_EQ(tiled.size(), 9u) << "R G B, direct.*, indirect.*";
  for (const auto& [name, values] : whole) {
    ASSERT_TRUE(tiled.count(name)) << name;
    EXPECT_TRUE(tiled.at(name) == values) << name << " differs";
  }
}

// The image phase over TCP (PROTOCOL.md section 3.4): a coordinator and two node processes
// solve the Cornell box and render its final gather in 32-pixel tiles. Node p1 is stopped
// (SIGSTOP) as soon as the status shows its FINAL in: the phase starts only with every FINAL
// in and grants each node two tiles at once, so p1 holds tiles it never sends (or, had it
// already rendered some, the ones granted after them: a node's grants are topped up while
// tiles are free). The image cannot be finished without dropping p1, which the coordinator
// does when p1 falls silent (5 s here); p0 renders p1's tiles. The run's EXR is, in every pass
// and bit for bit, the one `sirad image` renders from the run's PLY on one machine.
TEST(Processes, AnImageInTilesOverTcpIsTheImageOfOneMachineThoughANodeStops) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("sirad_tiles_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path status = dir / "status.json";
  const std::vector<std::string> view = {"--width", "256", "--height", "256"};
  std::vector<std::string> args = {SIRAD_COORDINATOR_BINARY, "cornell", "--listen", "tcp://127.0.0.1:*", "--insecure",
                                   "--endpoint-file", (dir / "endpoint").string(), "--min-nodes", "2", "--timeout",
                                   sirad::test::kHangTimeout, "--heartbeat-ms", "200", "--liveness", "25", "--status-json",
                                   status.string(), "--patches", "300", "--bundles", "256", "--final-gather", "128",
                                   "--out", (dir / "run").string(), "-q"};
  args.insert(args.end(), view.begin(), view.end());
  Child coordinator(args, dir / "coordinator.log");
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  const std::string endpoint = slurp(dir / "endpoint");
  auto node = [&](const char* name) {
    return std::make_unique<Child>(std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--insecure", "--name", name},
                                   dir / fmt::format("{}.log", name));
  };
  auto p0 = node("p0"), p1 = node("p1");
  auto final_in = [&] {
    for (const auto& n : status_nodes(status))
      if (n.name == "p1" && n.state == "done") return true;
    return false;
  };
  ASSERT_TRUE(wait_until(final_in)) << "p1's FINAL never came: " << slurp(dir / "coordinator.log");
  p1->pause();
  ASSERT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator.log");
  const std::string log = slurp(dir / "coordinator.log");
  EXPECT_NE(log.find("p1: dropped from the image (silent"), std::string::npos)
      << "p1 was not dropped: the image was finished before p1 stopped (make it larger)\n" << log;
  EXPECT_NE(log.find("image: 64 tiles in "), std::string::npos) << log;
  const sirad::cluster::Status last = sirad::cluster::read_status(status.string());
  EXPECT_EQ(last.image_tiles, 64u);
  EXPECT_EQ(last.image_tiles_done, 64u);
  uint64_t tiles = 0;
  for (const auto& n : last.nodes) tiles += n.tiles;
  EXPECT_EQ(tiles, 64u) << "every tile from a node, none twice";
  p1->kill9();
  p0->terminate();
  expect_the_image_of_one_machine(dir, "128", view);
  if (!HasFailure()) fs::remove_all(dir);
}

// A coordinator stopped (SIGTERM) during its image checkpoints the run with every bundle done;
// resumed, it has none of its nodes: it waits for --min-nodes (2) to join, which come as to a
// run (HELLO, WELCOME, READY), get a STOP that says the image follows, answer with a FINAL that
// is not taken and render every tile, and the image is `sirad image`'s of the run's PLY bit for
// bit. The first run is held in its image by stopping both nodes as soon as each has logged its
// FINAL: the 64 tiles take seconds, and until the nodes are silent for the liveness window
// (20 s) nobody else renders them. The resumed coordinator is given no image flags: the
// checkpoint carries them (before, it drew a 512 x 512 image of the patches instead).
TEST(Processes, ACoordinatorStoppedInItsImageResumesItOnNodesThatJoin) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("sirad_image_resume_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path status = dir / "status.json", checkpoint = dir / "run.checkpoint";
  const std::vector<std::string> image_flags = {"--final-gather", "128", "--width", "256", "--height", "256"};
  auto coordinator = [&](const std::string& listen, std::vector<std::string> extra, int n) {
    std::vector<std::string> args = {SIRAD_COORDINATOR_BINARY, "cornell", "--listen", listen, "--insecure", "--endpoint-file",
                                     (dir / "endpoint").string(), "--min-nodes", "2", "--timeout", sirad::test::kHangTimeout,
                                     "--heartbeat-ms", "200", "--liveness", "100", "--status-json", status.string(),
                                     "--checkpoint", checkpoint.string(), "--out", (dir / "run").string(), "-q"};
    if (n == 0) args.insert(args.end(), image_flags.begin(), image_flags.end());
    args.insert(args.end(), extra.begin(), extra.end());
    fs::remove(status);
    return std::make_unique<Child>(args, dir / fmt::format("coordinator{}.log", n));
  };
  std::string endpoint;  // the first coordinator's; the resumed one listens on it too
  auto node = [&](const std::string& name) {
    return std::make_unique<Child>(std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--insecure", "--name", name},
                                   dir / fmt::format("{}.log", name));
  };
  auto first = coordinator("tcp://127.0.0.1:*", {"--patches", "300", "--bundles", "256"}, 0);
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", *first)) << slurp(dir / "coordinator0.log");
  endpoint = slurp(dir / "endpoint");
  auto p0 = node("p0"), p1 = node("p1");
  for (const auto& [n, name] : {std::pair{p0.get(), "p0"}, std::pair{p1.get(), "p1"}}) {
    ASSERT_TRUE(wait_until([&] { return slurp(dir / fmt::format("{}.log", name)).find("final state sent") != std::string::npos; }))
        << name << " never sent its FINAL: " << slurp(dir / "coordinator0.log");
    n->pause();
  }
  first->terminate();
  EXPECT_NE(first->wait(sirad::test::kHangS), 0) << "the image was finished before the nodes stopped (make it larger)";
  const std::string log0 = slurp(dir / "coordinator0.log");
  ASSERT_NE(log0.find("interrupted after 256 bundles"), std::string::npos) << log0;
  p0->kill9();
  p1->kill9();

  auto second = coordinator(endpoint, {"--resume", checkpoint.string()}, 1);
  auto p2 = node("p2"), p3 = node("p3");
  ASSERT_EQ(second->wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator1.log");
  const sirad::cluster::Status last = sirad::cluster::read_status(status.string());
  EXPECT_EQ(last.image_tiles_done, 64u);
  uint64_t tiles = 0;
  for (const auto& n : last.nodes) {
    tiles += n.tiles;
    if (n.name == "p2" || n.name == "p3") EXPECT_GT(n.tiles, 0u) << n.name << " joined the image but rendered none of it";
    else EXPECT_EQ(n.tiles, 0u) << n.name;
  }
  EXPECT_EQ(tiles, 64u) << "every tile from a node that joined, none here\n" << slurp(dir / "coordinator1.log");
  for (const char* name : {"p2", "p3"}) {
    const std::string nlog = slurp(dir / fmt::format("{}.log", name));
    EXPECT_NE(nlog.find("image done: "), std::string::npos) << nlog;
    EXPECT_EQ(nlog.find(": coordinator: "), std::string::npos) << "an error from the coordinator\n" << nlog;
  }
  p2->terminate();
  p3->terminate();
  expect_the_image_of_one_machine(dir, "128", {"--width", "256", "--height", "256"});
  if (!HasFailure()) fs::remove_all(dir);
}

// Repetitions of the kill tests: SIRAD_KILL_REPEAT (default 1; 20 for the soak).
int kill_repeats() {
  const char* r = std::getenv("SIRAD_KILL_REPEAT");
  return r ? std::max(1, std::atoi(r)) : 1;
}

// kill -9 one of three node processes mid-run: the run completes with exactly the requested
// bundles (the ledger covers every index once: the dead node's unfinished grants were run by
// the others, nothing twice), the dead node is reported dead, and the furnace stays exact: its
// mean is 2 within 4 sd of a chain average of K = 16384 bundles (0.0097 sqrt(1024 / 16384) 4 =
// 0.0097, the sd of the plain transport with random directions, which the run uses: the control
// variate would make the furnace exact whatever the weights; K is large for the run to last
// the seconds a kill needs). SIRAD_KILL_REPEAT=20
// repeats it.
TEST(Processes, KillNineOneOfThreeNodesMidRun) {
  for (int rep = 0; rep < kill_repeats(); ++rep) {
    SCOPED_TRACE(rep);
    fs::path dir = fs::temp_directory_path() / fmt::format("sirad_kill_{}_{}", ::getpid(), rep);
    fs::remove_all(dir);
    fs::create_directories(dir);
    KillRun r = run_with_kill(dir, {"furnace", "--patches", "300", "--exchange-every", "16", "--control-variate", "off",
                                    "--directions", "random", "--shots-per-bundle", "0", "--out",
                                    (dir / "furnace").string(), "--width", "16", "--height", "16"},
                              16384, false);
    ASSERT_EQ(r.status, 0) << r.log;
    EXPECT_LT(r.done_at_kill, 16384u) << "the kill came after the run";
    EXPECT_NE(r.log.find("node p1: "), std::string::npos);
    EXPECT_NE(r.log.find(", dead\n"), std::string::npos) << r.log;
    EXPECT_NE(r.log.find("bundles 16384,"), std::string::npos) << r.log;
    expect_every_index_once(r.ledger, 16384);
    std::vector<glm::vec3> radiosity = ply_radiosity(dir / "furnace.ply");
    double sum = 0.0;
    for (const auto& v : radiosity) sum += v.x;
    double mean = sum / static_cast<double>(radiosity.size());
    std::printf("kill -9 at %llu of 16384 bundles: furnace mean %.4f\n", static_cast<unsigned long long>(r.done_at_kill), mean);
    EXPECT_NEAR(mean, 2.0, 0.0097 * std::sqrt(1024.0 / 16384) * 4);
    EXPECT_NE(r.log.find("declared dead"), std::string::npos);
    if (!HasFailure()) fs::remove_all(dir);
  }
}

// The Cornell box with one of three node processes killed mid-run agrees with undisturbed
// single-node runs of the same bundle count, as the undisturbed cluster does (the test above,
// same tolerances): the dead node's accepted state stays, its unfinished grants run elsewhere.
// Sync exchanges over links of 10 ms latency make the run last seconds (>= 20 ms a round of
// 3 x 16 bundles), long enough to kill a node in the middle; the barrier must not wait on it.
TEST(Processes, CornellWithANodeKilledAgreesWithSingleNodeRuns) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_cornell_kill_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "wan.yaml") << "defaults:\n  latency_ms: 10\n";
  KillRun r = run_with_kill(dir, {"cornell", "--patches", "300", "--seed", "99", "--exchange-every", "16", "--mode",
                                  "sync", "--profile", (dir / "wan.yaml").string(), "--shots-per-bundle", "0", "--out",
                                  (dir / "cluster").string(), "--width", "16", "--height", "16"},
                            4096, false);
  ASSERT_EQ(r.status, 0) << r.log;
  EXPECT_LT(r.done_at_kill, 4096u) << "the kill came after the run";
  EXPECT_NE(r.log.find("declared dead"), std::string::npos) << r.log;
  expect_every_index_once(r.ledger, 4096);
  expect_agrees_with_single_runs(ply_radiosity(dir / "cluster.ply"), 4096);
  fs::remove_all(dir);
}

// Kill a node and start it again: the new process (same name, new routing id) rejoins as a new
// node and takes grants; the ledger has every index exactly once across the dead p1, the new
// p1 and the others (a late report about a grant given away would be refused, never counted).
TEST(Processes, AKilledNodeRestartsAndRejoinsWithoutCountingTwice) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_restart_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  KillRun r = run_with_kill(dir, {"furnace", "--patches", "300", "--exchange-every", "16", "--out",
                                  (dir / "furnace").string(), "--width", "16", "--height", "16"},
                            16384, true);
  ASSERT_EQ(r.status, 0) << r.log;
  expect_every_index_once(r.ledger, 16384);
  std::map<uint32_t, uint64_t> p1;  // p1's entries by node index: the dead one and the rejoined one
  for (const LedgerRow& row : r.ledger)
    if (row.name == "p1") p1[row.node] += row.last - row.first;
  EXPECT_EQ(p1.size(), 2u) << r.log;
  for (const auto& [index, n] : p1) EXPECT_GT(n, 0u) << "p1 as node " << index;
  fs::remove_all(dir);
}

// SIGINT on `sirad render` ends the run with the bundles done so far and writes them (the
// estimate is unbiased at any count): exit status 130, the three outputs with the bundle count
// the stdout line gives, finite values. The run asks for 10^9 bundles, so it
// cannot end on its own while the test waits for its start line and signals.
TEST(Processes, RenderInterruptedWritesTheResultSoFar) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_sigint_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  Child render({SIRAD_BINARY, "render", "furnace", "--patches", "200", "--bundles", "1000000000", "--shots-per-bundle", "0", "--out",
                (dir / "partial").string(), "--width", "16", "--height", "16"},
               dir / "render.log");
  ASSERT_TRUE(wait_until([&] { return slurp(dir / "render.log").find(" patches, grid ") != std::string::npos; }, sirad::test::kHangS))
      << slurp(dir / "render.log");
  render.interrupt();
  ASSERT_EQ(render.wait(sirad::test::kHangS), 130) << slurp(dir / "render.log");
  std::string log = slurp(dir / "render.log");
  EXPECT_NE(log.find("ended early: interrupted (SIGINT)"), std::string::npos) << log;
  EXPECT_NE(log.find("interrupted after "), std::string::npos) << log;
  for (const char* ext : {".exr", ".png", ".ply"}) EXPECT_TRUE(fs::exists(dir / (std::string("partial") + ext))) << ext;
  // The bundle count said on stdout is the EXR's, and at least one bundle ran.
  auto at = log.find("interrupted after ");
  ASSERT_NE(at, std::string::npos);
  const long long said = std::stoll(log.substr(at + 18));
  Imf::InputFile exr((dir / "partial.exr").string().c_str());
  auto* bundles = exr.header().findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
  ASSERT_NE(bundles, nullptr);
  EXPECT_EQ(bundles->value(), said);
  EXPECT_GE(said, 1);
  EXPECT_LT(said, 1000000000);
  std::vector<glm::vec3> radiosity = ply_radiosity(dir / "partial.ply");
  ASSERT_FALSE(radiosity.empty());
  for (const auto& v : radiosity) EXPECT_TRUE(std::isfinite(v.x) && v.x > 0.0f) << v.x;
  fs::remove_all(dir);
}

// Waits until the status JSON says at least `bundles` are done (a hang, past kHangS, fails the
// test); returns them.
uint64_t wait_for_bundles(const fs::path& status, uint64_t bundles) {
  EXPECT_TRUE(wait_until([&] { return bundles_done(status) >= bundles; }, sirad::test::kHangS)) << "never " << bundles << " bundles";
  return bundles_done(status);
}

// The coordinator dies and is resumed from its checkpoint, twice, while 3 node processes keep
// running and reconnect on their own: first kill -9 (the periodic checkpoint, every 0.2 s),
// with the nodes stopped meanwhile so that the run cannot end before the kill,
// then SIGTERM (it writes a checkpoint and exits non-zero, saying how to resume). The last
// coordinator finishes with exactly K bundles, every index once in its ledger (the nodes of
// every incarnation), each node process in the run 3 times (it rejoined each new coordinator
// as a new node), and the furnace unbiased within 4 sd of a K-bundle chain average
// (0.0097 sqrt(1024 / K) 4; plain transport, random directions, as the derivation assumes). Sync exchanges over 10 ms links make the run last seconds.
TEST(Processes, KilledCoordinatorResumesFromItsCheckpoint) {
  const uint64_t K = 8192;
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_resume_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "wan.yaml") << "defaults:\n  latency_ms: 10\n";
  auto coordinator = [&](const std::string& listen, std::vector<std::string> extra, int n) {
    std::vector<std::string> args = {SIRAD_COORDINATOR_BINARY, "furnace", "--listen", listen, "--insecure",
                                     "--endpoint-file", (dir / "endpoint").string(), "--timeout", sirad::test::kHangTimeout,
                                     "--heartbeat-ms", "200", "--liveness", "100", "--status-json", (dir / "status.json").string(),
                                     "--checkpoint", (dir / "run.checkpoint").string(), "--checkpoint-every", "0.2",
                                     "--ledger", (dir / "ledger.csv").string(), "--profile", (dir / "wan.yaml").string(),
                                     "--out", (dir / "furnace").string(), "--width", "16", "--height", "16", "-q"};
    args.insert(args.end(), extra.begin(), extra.end());
    fs::remove(dir / "status.json");
    return std::make_unique<Child>(args, dir / fmt::format("coordinator{}.log", n));
  };
  auto first = coordinator("tcp://127.0.0.1:*", {"--patches", "300", "--bundles", std::to_string(K), "--exchange-every",
                                                 "16", "--mode", "sync", "--min-nodes", "3", "--control-variate", "off",
                                                 "--directions", "random", "--shots-per-bundle", "0"},
                           0);
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", *first)) << slurp(dir / "coordinator0.log");
  const std::string endpoint = slurp(dir / "endpoint");
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, endpoint, "p", 3);
  // Stops every node (the sync run cannot move on while they are stopped: --liveness keeps them
  // alive for 20 s) and waits for a checkpoint written after that.
  auto hold = [&] {
    for (auto& n : nodes) n->pause();
    auto before = fs::last_write_time(dir / "run.checkpoint");
    EXPECT_TRUE(wait_until([&] { return fs::last_write_time(dir / "run.checkpoint") != before; }, sirad::test::kHangS));
  };
  auto release = [&] {
    for (auto& n : nodes) n->resume();
  };
  uint64_t at_kill = wait_for_bundles(dir / "status.json", K / 4);
  ASSERT_TRUE(wait_until([&] { return fs::exists(dir / "run.checkpoint"); }, sirad::test::kHangS));
  hold();
  first->kill9();
  ASSERT_EQ(first->wait(sirad::test::kHangS), 128 + SIGKILL);
  ASSERT_TRUE(fs::exists(dir / "run.checkpoint"));
  ASSERT_LT(at_kill, K) << "the kill came after the run";
  // The same endpoint; the settings come from the checkpoint.
  auto second = coordinator(endpoint, {"--resume", (dir / "run.checkpoint").string()}, 1);
  release();
  uint64_t at_term = wait_for_bundles(dir / "status.json", at_kill + K / 8);
  hold();
  second->terminate();
  EXPECT_NE(second->wait(sirad::test::kHangS), 0);
  std::string log1 = slurp(dir / "coordinator1.log");
  EXPECT_NE(log1.find("resumed after"), std::string::npos) << log1;
  EXPECT_NE(log1.find("interrupted after"), std::string::npos) << log1;
  EXPECT_NE(log1.find("--resume"), std::string::npos) << log1;
  ASSERT_LT(at_term, K) << "the SIGTERM came after the run";
  auto third = coordinator(endpoint, {"--resume", (dir / "run.checkpoint").string()}, 2);
  release();
  ASSERT_EQ(third->wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator2.log");
  std::string log = slurp(dir / "coordinator2.log");
  std::printf("coordinator killed at %llu, terminated at %llu of %llu bundles\n", static_cast<unsigned long long>(at_kill),
              static_cast<unsigned long long>(at_term), static_cast<unsigned long long>(K));
  // The summary counts this run's nodes and rates; the run before the resumes is said apart
  // (its 6 node entries: the 3 processes in each of the two earlier coordinators).
  const auto resumed_at = log.find("bundles done by 6 nodes");
  ASSERT_NE(resumed_at, std::string::npos) << log;
  const auto of = log.rfind(" of ", resumed_at);
  const uint64_t before = std::stoull(log.substr(log.rfind(": ", of) + 2));
  EXPECT_NE(log.find(fmt::format("bundles {},", K - before)), std::string::npos) << log;
  EXPECT_NE(log.find(", nodes 3,"), std::string::npos) << log;
  EXPECT_NE(log.find(fmt::format("by 6 nodes ({} in all)", K)), std::string::npos) << log;
  // The nodes rejoined each new coordinator the protocol's way: no error from it in their logs.
  for (int i = 0; i < 3; ++i) {
    std::string nlog = slurp(dir / fmt::format("node{}.log", i));
    EXPECT_EQ(nlog.find(": coordinator: "), std::string::npos) << nlog;
  }
  std::vector<LedgerRow> ledger = read_ledger(dir / "ledger.csv");
  expect_every_index_once(ledger, K);
  std::map<std::string, std::set<uint32_t>> entries;  // each process's node indices
  for (const LedgerRow& row : ledger) entries[row.name].insert(row.node);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(entries[fmt::format("p{}", i)].size(), 3u) << "p" << i << " in each incarnation\n" << log;
  std::vector<glm::vec3> radiosity = ply_radiosity(dir / "furnace.ply");
  double sum = 0.0;
  for (const auto& v : radiosity) sum += v.x;
  EXPECT_NEAR(sum / static_cast<double>(radiosity.size()), 2.0, 0.0097 * std::sqrt(1024.0 / K) * 4);
  for (auto& n : nodes) n->terminate();
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace

// The scene is sent to a node once and kept by its hash (PROTOCOL.md 3.1, node/scene_cache.h):
// three coordinator runs in turn on one ipc endpoint. Run 1 sends the furnace to a node started
// with --scene-cache; run 2 (the same scene meshed to another patch count: the cache is keyed
// by the scene, not the mesh) finds it held in that node's memory and sends nothing; run 3, after
// the node process is replaced by a new one on the same folder, finds it on disk. Each run ends
// with the furnace right (mean 2 within 4 standard deviations of a 256-bundle average:
// 0.0097 * sqrt(1024 / 256) * 4 = 0.078), and the status counts the scenes sent and found.
TEST(Processes, ANodeIsSentTheSceneOnceAndKeepsItByHash) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_cache_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string endpoint = "ipc://" + (dir / "coordinator.sock").string();
  auto run = [&](int i, const char* patches) {
    const fs::path status = dir / fmt::format("status{}.json", i);
    Child coordinator({SIRAD_COORDINATOR_BINARY, "furnace", "--listen", endpoint, "--min-nodes", "1", "--bundles", "256",
                       "--patches", patches, "--status-json", status.string(), "--out", (dir / fmt::format("furnace{}", i)).string(),
                       "--width", "16", "--height", "16", "--timeout", sirad::test::kHangTimeout, "-q"},
                      dir / fmt::format("coordinator{}.log", i));
    EXPECT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir / fmt::format("coordinator{}.log", i));
    std::vector<glm::vec3> radiosity = ply_radiosity(dir / fmt::format("furnace{}.ply", i));
    double sum = 0.0;
    for (const auto& r : radiosity) sum += r.x;
    EXPECT_NEAR(sum / static_cast<double>(std::max<std::size_t>(radiosity.size(), 1)), 2.0, 0.078) << "run " << i;
    return sirad::cluster::read_status(status.string());
  };
  auto node = [&](const char* name) {
    return std::make_unique<Child>(std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--name", name,
                                                            "--scene-cache", (dir / "cache").string()},
                                   dir / fmt::format("{}.log", name));
  };
  auto first = node("n1");
  sirad::cluster::Status s1 = run(1, "300");
  EXPECT_EQ(s1.scenes_sent, 1u);
  EXPECT_EQ(s1.scenes_from_cache, 0u);
  int files = 0;
  for (const auto& f : fs::directory_iterator(dir / "cache")) files += f.path().extension() == ".scene";
  EXPECT_EQ(files, 1);
  sirad::cluster::Status s2 = run(2, "200");
  EXPECT_EQ(s2.scenes_sent, 0u);
  EXPECT_EQ(s2.scenes_from_cache, 1u);
  EXPECT_NE(slurp(dir / "n1.log").find("from the cache"), std::string::npos) << slurp(dir / "n1.log");
  first->terminate();
  EXPECT_EQ(first->wait(sirad::test::kHangS), 0);
  auto second = node("n2");
  sirad::cluster::Status s3 = run(3, "300");
  EXPECT_EQ(s3.scenes_sent, 0u);
  EXPECT_EQ(s3.scenes_from_cache, 1u);
  second->terminate();
  EXPECT_EQ(second->wait(sirad::test::kHangS), 0);
  fs::remove_all(dir);
}
