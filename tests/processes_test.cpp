// sirad tests: the cluster as separate processes: one sirad-coordinator and three sirad-node
// processes over loopback TCP on a port the system picks (never a fixed one).
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <chrono>
#include <cstring>
#include <memory>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

extern char** environ;
namespace fs = std::filesystem;

namespace {

// A child process, killed if still running when it goes out of scope.
class Child {
 public:
  Child(std::vector<std::string> args, const fs::path& log) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Child() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  // Exit status, or -1 if it has not exited within `seconds`.
  int wait(double seconds) {
    auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }
  void terminate() { ::kill(pid_, SIGTERM); }
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Coordinator plus 3 node processes over loopback TCP: the run completes with every bundle
// done once (the per-node counts add up to K, the ledger refuses repeats), the outputs are
// written, the nodes stop cleanly on SIGTERM, and the furnace's mean is 2 within 4 standard
// deviations of a 512-bundle chain average (0.0097 * sqrt(1024 / 512) * 4 = 0.055).
TEST(Processes, CoordinatorAndThreeNodesOverTcp) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_proc_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  Child coordinator({SIRAD_COORDINATOR_BINARY, "furnace", "--listen", "tcp://127.0.0.1:*", "--endpoint-file",
                     (dir / "endpoint").string(), "--bundles", "512", "--patches", "300", "--min-nodes", "3",
                     "--exchange-every", "16", "--out", (dir / "furnace").string(), "--width", "16", "--height", "16",
                     "--timeout", "120"},
                    dir / "coordinator.log");
  ASSERT_TRUE(coordinator.started());
  for (int i = 0; i < 200 && !fs::exists(dir / "endpoint"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::string endpoint = slurp(dir / "endpoint");
  ASSERT_EQ(endpoint.rfind("tcp://127.0.0.1:", 0), 0u) << endpoint;
  std::vector<std::unique_ptr<Child>> nodes;
  for (int i = 0; i < 3; ++i)
    nodes.push_back(std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--name", fmt::format("p{}", i)},
        dir / fmt::format("node{}.log", i)));
  ASSERT_EQ(coordinator.wait(150), 0) << slurp(dir / "coordinator.log");
  std::string log = slurp(dir / "coordinator.log");
  uint64_t total = 0;
  for (int i = 0; i < 3; ++i) {
    auto at = log.find(fmt::format("node p{}: ", i));
    ASSERT_NE(at, std::string::npos) << log;
    total += std::stoull(log.substr(at + 9));
  }
  EXPECT_EQ(total, 512u) << log;
  for (const char* ext : {".exr", ".png", ".ply"}) EXPECT_TRUE(fs::exists(dir / (std::string("furnace") + ext)));
  // The furnace's mean, from the PLY's per-face radiosity (after the header: float vertices,
  // then per face: uchar 3, three ints, nine floats).
  std::string ply = slurp(dir / "furnace.ply");
  auto header_end = ply.find("end_header\n") + 11;
  auto count_of = [&](const std::string& element) {
    auto at = ply.find("element " + element + " ");
    return std::stoull(ply.substr(at + 9 + element.size()));
  };
  uint64_t vertices = count_of("vertex"), faces = count_of("face");
  const char* p = ply.data() + header_end + vertices * 12;
  double sum = 0.0;
  for (uint64_t f = 0; f < faces; ++f) {
    float r;
    std::memcpy(&r, p + 1 + 12, 4);
    sum += r;
    p += 1 + 12 + 36;
  }
  double mean = sum / static_cast<double>(faces);  // the furnace's patches have nearly equal areas
  std::printf("3 node processes, furnace: mean radiosity %.4f\n", mean);
  EXPECT_NEAR(mean, 2.0, 0.055);
  for (auto& n : nodes) {
    n->terminate();
    EXPECT_EQ(n->wait(10), 0);
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
  ASSERT_EQ(e.wait(120), 0) << slurp(dir / "embedded.log");
  std::vector<std::string> coord = {SIRAD_COORDINATOR_BINARY, "cornell", "--listen", "tcp://127.0.0.1:*", "-q",
                                    "--endpoint-file", (dir / "endpoint").string(), "--out", (dir / "tcp").string(),
                                    "--timeout", "120"};
  coord.insert(coord.end(), run.begin(), run.end());
  Child coordinator(coord, dir / "coordinator.log");
  for (int i = 0; i < 200 && !fs::exists(dir / "endpoint"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  Child node({SIRAD_NODE_BINARY, "--connect", slurp(dir / "endpoint"), "--name", "tcp-node"}, dir / "node.log");
  ASSERT_EQ(coordinator.wait(150), 0) << slurp(dir / "coordinator.log");
  std::string a = slurp(dir / "embedded.ply"), b = slurp(dir / "tcp.ply");
  ASSERT_GT(a.size(), 1000u);
  EXPECT_TRUE(a == b) << "the embedded default and the TCP cluster differ";
  node.terminate();
  EXPECT_EQ(node.wait(10), 0);
  fs::remove_all(dir);
}

}  // namespace
