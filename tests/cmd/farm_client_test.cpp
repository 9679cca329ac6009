// sirad tests: `sirad jobs`, `sirad submit` and `sirad cancel` (farm/farm_client.h) run as
// processes against a farm this test plays (cpp-httplib on 127.0.0.1, a port the system picks):
// a hostile farm's answer nested 200,000 levels deep, or larger than the client reads, is one
// clear error, not a crash or gigabytes of memory; a submission's parts and token arrive as the
// farm reads them.
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "scene/encoding.h"
#include "scene/scene.h"
#include "tests/process_util.h"
#include "tests/test_folder.h"
#include "util/json_bounded.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;
using test::Child;
using test::slurp;

// A farm played by the test: `routes` sets its answers; it serves from a thread until destroyed.
class FakeFarm {
 public:
  explicit FakeFarm(const std::function<void(httplib::Server&)>& routes) {
    routes(server_);
    port_ = server_.bind_to_any_port("127.0.0.1");  // listening from here: a client's connection waits for the thread
    thread_ = std::thread([this] { server_.listen_after_bind(); });
  }
  ~FakeFarm() {
    server_.stop();
    thread_.join();
  }
  std::string url() const { return fmt::format("http://127.0.0.1:{}", port_); }

 private:
  httplib::Server server_;
  int port_ = -1;
  std::thread thread_;
};

struct Outcome {
  int status;
  std::string said;
};

// `sirad ARGS` run to its end: its exit status (128 + signal when a signal ended it) and output.
Outcome sirad(const fs::path& dir, std::vector<std::string> args) {
  args.insert(args.begin(), SIRAD_BINARY);
  Child c(args, dir / "client.log");
  const int status = c.wait(test::kHangS);
  return {status, slurp(dir / "client.log")};
}

class FarmClient : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = sirad::test::fresh_test_folder("sirad_farm_client");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// An answer whose list of jobs nests 200,000 levels deep (it overflowed the client's stack) is
// refused by its depth, naming the farm.
TEST_F(FarmClient, AnAnswerNestedTooDeepIsOneError) {
  const std::string deep = R"({"jobs": )" + std::string(200000, '[') + std::string(200000, ']') + "}";
  FakeFarm farm([&](httplib::Server& s) {
    s.Get("/api/jobs", [&](const httplib::Request&, httplib::Response& res) { res.set_content(deep, "application/json"); });
  });
  const Outcome r = sirad(dir_, {"jobs", "--farm", farm.url()});
  EXPECT_EQ(r.status, 1) << r.said;
  EXPECT_NE(r.said.find(fmt::format("jobs: the answer of the farm at {}: JSON nested deeper than {} levels", farm.url(), kMaxJsonDepth)),
            std::string::npos)
      << r.said;
}

// An answer of 128 MiB (valid JSON: an empty list and a long string) is cut off once it passes
// the client's 64 MiB, while it arrives.
TEST_F(FarmClient, AnAnswerLargerThanTheClientReadsIsCutOff) {
  constexpr std::size_t kPad = std::size_t{128} << 20;
  const std::string head = R"({"jobs": [], "pad": ")", tail = R"("})";
  FakeFarm farm([&](httplib::Server& s) {
    s.Get("/api/jobs", [&](const httplib::Request&, httplib::Response& res) {
      res.set_content_provider(head.size() + kPad + tail.size(), "application/json",
                               [&](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                                 std::string piece;
                                 for (std::size_t at = offset; at < offset + length && piece.size() < (1u << 20); ++at)
                                   piece += at < head.size() ? head[at] : at < head.size() + kPad ? 'x' : tail[at - head.size() - kPad];
                                 return sink.write(piece.data(), piece.size());
                               });
    });
  });
  const Outcome r = sirad(dir_, {"jobs", "--farm", farm.url()});
  EXPECT_EQ(r.status, 1) << r.said.substr(0, 2000);
  EXPECT_NE(r.said.find(fmt::format("jobs: the farm at {} answered with more than 64 MiB", farm.url())), std::string::npos)
      << r.said.substr(0, 2000);
}

// `sirad submit` of a scene file: the farm reads the job's JSON and the encoded scene from the
// multipart form the client writes, with the token; `sirad cancel` reaches its job.
TEST_F(FarmClient, SubmitAndCancelSendWhatTheFarmReads) {
  std::mutex m;
  std::string auth, job, scene_data;
  bool cancelled = false;
  FakeFarm farm([&](httplib::Server& s) {
    s.Post("/api/jobs", [&](const httplib::Request& req, httplib::Response& res) {
      std::lock_guard lock(m);
      auth = req.get_header_value("Authorization");
      if (req.has_file("job")) job = req.get_file_value("job").content;
      if (req.has_file("scene_data")) scene_data = req.get_file_value("scene_data").content;
      res.status = 201;
      res.set_content(R"({"id": 7, "name": "box", "state": "queued"})", "application/json");
    });
    s.Post("/api/jobs/7/cancel", [&](const httplib::Request& req, httplib::Response& res) {
      std::lock_guard lock(m);
      cancelled = req.get_header_value("Authorization") == "Bearer s3cret";
      res.set_content(R"({"id": 7, "state": "cancelled"})", "application/json");
    });
  });
  std::ofstream(dir_ / "token") << "s3cret\n";
  const std::string scene = std::string(SIRAD_SOURCE_DIR) + "/scenes/cornell_box.obj";
  const Outcome submitted = sirad(dir_, {"submit", scene, "--farm", farm.url(), "--token-file", (dir_ / "token").string(), "--name", "box",
                                     "--priority", "3", "--bundles", "16"});
  ASSERT_EQ(submitted.status, 0) << submitted.said;
  EXPECT_NE(submitted.said.find("submitted job 7 (box)"), std::string::npos) << submitted.said;
  const Outcome cancel = sirad(dir_, {"cancel", "7", "--farm", farm.url(), "--token-file", (dir_ / "token").string()});
  EXPECT_EQ(cancel.status, 0) << cancel.said;
  std::lock_guard lock(m);
  EXPECT_EQ(auth, "Bearer s3cret");
  EXPECT_TRUE(cancelled);
  const nlohmann::json spec = nlohmann::json::parse(job);
  EXPECT_EQ(spec.value("name", ""), "box");
  EXPECT_EQ(spec.value("priority", 0), 3);
  EXPECT_EQ(decode_scene(scene_data, "the upload").triangles.size(), load_scene(scene).triangles.size());
}

}  // namespace
}  // namespace sirad
