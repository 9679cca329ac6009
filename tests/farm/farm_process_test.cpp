// sirad tests: the farm as processes (sirad-coordinator --serve; farm/farm.h): its queue, its
// nodes shared between jobs, a farm killed and restarted, its page in a headless browser, hostile
// jobs and slow clients, over loopback TCP on ports the system picks.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cluster/jobs.h"
#include "cluster/status.h"
#include "farm/http_guard.h"
#include "farm/view_server.h"
#include "tests/png_util.h"
#include "tests/process_util.h"
#include "tests/run_files.h"

namespace fs = std::filesystem;
using namespace sirad::test;  // the process helpers (process_util.h, run_files.h)

namespace {

// --- the farm (sirad-coordinator --serve; farm/farm.h) ------------------------------------

// A farm process over loopback TCP: its folder, ZeroMQ endpoint, HTTP URL and token.
struct FarmProcess {
  std::unique_ptr<Child> process;
  fs::path folder;
  std::string endpoint, url, token;
};

// Starts a farm in dir/farm listening on `listen`, and waits until its endpoint and HTTP
// address files are written (both removed first: a restarted farm writes them again).
FarmProcess start_farm(const fs::path& dir, const std::string& listen, int incarnation) {
  FarmProcess f;
  f.folder = dir / "farm";
  fs::remove(dir / "endpoint");
  fs::remove(f.folder / "http");
  f.process = std::make_unique<Child>(
      std::vector<std::string>{SIRAD_COORDINATOR_BINARY, "--serve", f.folder.string(), "--listen", listen, "--insecure",
                               "--endpoint-file", (dir / "endpoint").string(), "--http", "127.0.0.1:0", "--heartbeat-ms", "200",
                               "--liveness", "100", "--checkpoint-every", "0.2"},
      dir / fmt::format("farm{}.log", incarnation));
  EXPECT_TRUE(wait_until([&] { return fs::exists(dir / "endpoint") && fs::exists(f.folder / "http"); })) << slurp(dir / "farm0.log");
  f.endpoint = slurp(dir / "endpoint");
  f.url = slurp(f.folder / "http");
  f.token = slurp(f.folder / "token");
  return f;
}

// The end of a farm test: its nodes, then the farm, stopped by SIGTERM; the farm must exit 0 (it
// checkpoints its running jobs and leaves). The folder is removed when the test passed.
void stop_farm(FarmProcess& farm, std::vector<std::unique_ptr<Child>>& nodes, const fs::path& dir, const std::string& log) {
  for (auto& n : nodes) n->terminate();
  farm.process->terminate();
  EXPECT_EQ(farm.process->wait(sirad::test::kHangS), 0) << slurp(dir / log);
  if (!::testing::Test::HasFailure()) fs::remove_all(dir);
}

// A fresh folder for a farm test, under the temporary directory.
fs::path fresh_dir(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / fmt::format("{}_{}", name, ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// `sirad submit ARGS`, run to its end: its exit status (what it said in dir/submit.log).
int sirad_submit(const fs::path& dir, std::vector<std::string> args) {
  args.insert(args.begin(), {SIRAD_BINARY, "submit"});
  Child c(args, dir / "submit.log");
  return c.wait(sirad::test::kHangS);
}

// A job's record (job.json) as JSON; null while it cannot be read.
nlohmann::json job_record(const FarmProcess& f, int id) {
  try {
    return nlohmann::json::parse(slurp(f.folder / "jobs" / std::to_string(id) / "job.json"));
  } catch (const std::exception&) {
    return nullptr;
  }
}

std::string job_state(const FarmProcess& f, int id) {
  nlohmann::json j = job_record(f, id);
  return j.is_object() ? j.value("state", "") : "";
}

// curl (a client this project did not write) with `args`; its output and the HTTP status.
std::pair<std::string, int> curl(const fs::path& dir, std::vector<std::string> args) {
  static int n = 0;
  fs::path out = dir / fmt::format("curl{}.out", n++);
  const std::string program = sirad::test::on_path("curl");
  EXPECT_FALSE(program.empty()) << "curl is not installed (deploy/install-deps.sh installs it)";
  args.insert(args.begin(), {program, "-s", "-S", "-o", out.string(), "-w", "%{http_code}"});
  Child c(args, out.string() + ".status");
  EXPECT_EQ(c.wait(sirad::test::kHangS), 0) << slurp(out.string() + ".status");
  return {slurp(out), std::atoi(slurp(out.string() + ".status").c_str())};
}

// The Cornell box's red wall in an RGB image: pixels of high red and low green and blue.
std::size_t red_wall_pixels(const std::vector<unsigned char>& rgb) {
  std::size_t red = 0;
  for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) red += rgb[i] > 100 && rgb[i + 1] < 60 && rgb[i + 2] < 60;
  return red;
}

double furnace_mean(const fs::path& ply) {
  std::vector<glm::vec3> radiosity = ply_radiosity(ply);
  double sum = 0.0;
  for (const auto& v : radiosity) sum += v.x;
  return sum / static_cast<double>(radiosity.size());
}

// A farm with a queue of three jobs (submitted by `sirad submit` and by curl, before any node
// is there, so the order is the queue's alone) and two node processes over TCP: the highest
// priority runs first (a long furnace, cancelled through the API once it has run bundles: it
// ends cancelled, its checkpoint gone), then the next (priority 1), then the last (priority 0);
// each of the two that finish ran every bundle index once (its ledger), and the furnace's mean
// is 2 within 4 standard deviations of a 512-bundle plain chain average (0.0097 sqrt(1024 / 512)
// 4 = 0.055, the bound of Processes.CoordinatorAndThreeNodesOverTcp); the Cornell job's final
// gather is rendered in tiles by the nodes. Submitting without the token is refused (401); the
// API lists the jobs and hands out their images.
TEST(Farm, RunsItsQueueByPriorityAndACancelStopsTheRunningJob) {
  const fs::path dir = fresh_dir("sirad_farm");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  auto submit = [&](std::vector<std::string> args) { EXPECT_EQ(sirad_submit(dir, std::move(args)), 0) << slurp(dir / "submit.log"); };
  const std::vector<std::string> plain = {"--control-variate", "off", "--directions", "random", "--shots-per-bundle", "0",
                                          "--width", "8", "--height", "8"};
  std::vector<std::string> low = {"furnace", "--farm", farm.folder.string(), "--name", "low", "--patches", "200", "--bundles", "512",
                                  "--exchange-every", "16"};
  low.insert(low.end(), plain.begin(), plain.end());
  submit(low);  // job 1
  const std::string big = R"({"name": "big", "scene": "furnace", "priority": 5, "args": ["--patches", "200", "--bundles", "100000000", "--exchange-every", "16"]})";
  EXPECT_EQ(curl(dir, {"-F", "job=" + big, farm.url + "/api/jobs"}).second, 401);
  auto [made, code] = curl(dir, {"-H", "Authorization: Bearer " + farm.token, "-F", "job=" + big, farm.url + "/api/jobs"});
  ASSERT_EQ(code, 201) << made;  // job 2
  submit({"cornell", "--farm", farm.url, "--token-file", (farm.folder / "token").string(), "--name", "mid", "--priority", "1",
          "--patches", "300", "--bundles", "128", "--width", "40", "--height", "8", "--final-gather", "4"});  // job 3
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, farm.endpoint, "f", 2);
  ASSERT_TRUE(wait_until([&] { return bundles_done(farm.folder / "jobs" / "2" / "status.json") > 0; }))
      << "the highest priority never ran\n" << slurp(dir / "farm0.log");
  EXPECT_EQ(job_state(farm, 1), "queued");
  EXPECT_EQ(job_state(farm, 3), "queued");
  EXPECT_EQ(curl(dir, {"-d", "", farm.url + "/api/jobs/2/cancel"}).second, 401);  // no token: nothing changes
  EXPECT_EQ(curl(dir, {"-d", "", "-H", "Authorization: Bearer wrong-token-of-any-length", farm.url + "/api/jobs/2/cancel"}).second, 401);
  auto [cancelled, cancel_code] = curl(dir, {"-d", "", "-H", "Authorization: Bearer " + farm.token, farm.url + "/api/jobs/2/cancel"});
  ASSERT_EQ(cancel_code, 200) << cancelled;
  ASSERT_TRUE(wait_until([&] { return job_state(farm, 1) == "done" && job_state(farm, 3) == "done"; })) << slurp(dir / "farm0.log");
  EXPECT_EQ(job_state(farm, 2), "cancelled");
  EXPECT_FALSE(fs::exists(farm.folder / "jobs" / "2" / "checkpoint"));
  const nlohmann::json j1 = job_record(farm, 1), j2 = job_record(farm, 2), j3 = job_record(farm, 3);
  EXPECT_LT(j2["started"].get<double>(), j3["started"].get<double>());
  EXPECT_LE(j2["finished"].get<double>(), j3["started"].get<double>());
  EXPECT_LT(j3["started"].get<double>(), j1["started"].get<double>());
  expect_every_index_once(read_ledger(farm.folder / "jobs" / "1" / "ledger.csv"), 512);
  expect_every_index_once(read_ledger(farm.folder / "jobs" / "3" / "ledger.csv"), 128);
  // Job 3's final gather: its two tiles (40 x 8 in 32-pixel tiles) rendered by the job's nodes.
  const sirad::cluster::Status s3 = sirad::cluster::read_status((farm.folder / "jobs" / "3" / "status.json").string());
  EXPECT_EQ(s3.image_tiles, 2u);
  EXPECT_EQ(s3.image_tiles_done, 2u);
  uint64_t tiles = 0;
  for (const auto& n : s3.nodes) tiles += n.tiles;
  EXPECT_EQ(tiles, 2u) << "the job's tiles come from its nodes";
  EXPECT_NEAR(furnace_mean(farm.folder / "jobs" / "1" / "low.ply"), 2.0, 0.055);
  auto [list, list_code] = curl(dir, {farm.url + "/api/jobs"});
  EXPECT_EQ(list_code, 200);
  nlohmann::json jobs = nlohmann::json::parse(list)["jobs"];
  ASSERT_EQ(jobs.size(), 3u) << list;
  EXPECT_EQ(jobs[1]["state"], "cancelled");
  auto [png, png_code] = curl(dir, {farm.url + "/api/jobs/3/files/mid.png"});
  EXPECT_EQ(png_code, 200);
  EXPECT_EQ(png.substr(0, 4), "\x89PNG");
  EXPECT_EQ(curl(dir, {farm.url + "/api/jobs/3/files/job.json"}).second, 404);  // only outputs are handed out
  stop_farm(farm, nodes, dir, "farm0.log");
}

// Two jobs that cannot use every node share a farm of two node processes over TCP: a long
// Cornell box (priority 1, --max-nodes 1) and a short furnace (priority 0, --max-nodes 1). Run
// one after another, the short job would wait for the long one, which has 10^8 bundles: it
// ends done while the long job runs, each job's nodes are one node process and not the other's
// (their status and ledger), and the short one ran every bundle index once. While the long job
// runs, the farm writes its preview image from the states its node has sent (its status counts
// that node's traffic): a PNG showing the Cornell box's red wall, handed out by the API; a
// cancel then stops the long job and takes its previews (image and glb) away. A job whose --min-nodes exceeds its
// --max-nodes is refused when submitted, with one line.
TEST(Farm, JobsThatCannotUseEveryNodeShareTheFarm) {
  const fs::path dir = fresh_dir("sirad_farm_share");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  auto submit = [&](std::vector<std::string> args) { return sirad_submit(dir, std::move(args)); };
  ASSERT_EQ(submit({"cornell", "--farm", farm.folder.string(), "--name", "long", "--priority", "1", "--max-nodes", "1", "--patches",
                    "500", "--bundles", "100000000", "--exchange-every", "8", "--width", "64", "--height", "64"}),
            0) << slurp(dir / "submit.log");
  ASSERT_EQ(submit({"furnace", "--farm", farm.folder.string(), "--name", "short", "--max-nodes", "1", "--patches", "200", "--bundles",
                    "256", "--exchange-every", "16", "--width", "8", "--height", "8"}),
            0) << slurp(dir / "submit.log");
  EXPECT_EQ(submit({"furnace", "--farm", farm.folder.string(), "--min-nodes", "3", "--max-nodes", "2"}), 1);
  EXPECT_NE(slurp(dir / "submit.log").find("--min-nodes 3 is more than --max-nodes 2"), std::string::npos) << slurp(dir / "submit.log");
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, farm.endpoint, "s", 2);
  const fs::path long_dir = farm.folder / "jobs" / "1", short_dir = farm.folder / "jobs" / "2";
  ASSERT_TRUE(wait_until([&] { return job_state(farm, 2) == "done"; })) << "the short job waited\n" << slurp(dir / "farm0.log");
  EXPECT_EQ(job_state(farm, 1), "running");
  const std::vector<LedgerRow> short_ledger = read_ledger(short_dir / "ledger.csv");
  expect_every_index_once(short_ledger, 256);
  std::set<std::string> short_names;
  for (const LedgerRow& row : short_ledger) short_names.insert(row.name);
  ASSERT_EQ(short_names.size(), 1u);
  // The long job's node has sent states: its preview is there, and its traffic is counted.
  ASSERT_TRUE(wait_until([&] {
    return fs::exists(long_dir / "preview.png") && fs::exists(long_dir / "preview.glb") && !status_nodes(long_dir / "status.json").empty();
  })) << slurp(dir / "farm0.log");
  const std::vector<sirad::cluster::Status::Node> long_nodes = status_nodes(long_dir / "status.json");
  ASSERT_EQ(long_nodes.size(), 1u);
  EXPECT_EQ(short_names.count(long_nodes[0].name), 0u) << long_nodes[0].name << " ran both jobs";
  ASSERT_TRUE(wait_until([&] {
    auto n = status_nodes(long_dir / "status.json");
    return !n.empty() && n[0].bytes_in > 0 && n[0].bytes_out > 0;
  })) << slurp(long_dir / "status.json");
  auto [png, png_code] = curl(dir, {farm.url + "/api/jobs/1/files/preview.png"});
  ASSERT_EQ(png_code, 200);
  {
    std::ofstream(dir / "preview.png", std::ios::binary) << png;
    int width = 0, height = 0;
    std::vector<unsigned char> rgb = sirad::test::read_png((dir / "preview.png").string(), width, height);
    EXPECT_EQ(width, 64);
    EXPECT_GT(red_wall_pixels(rgb), 64u * 64 / 20) << "no red wall in the preview";
  }
  auto [glb, glb_code] = curl(dir, {farm.url + "/api/jobs/1/glb"});  // its 3D view's: the preview's
  EXPECT_EQ(glb_code, 200);
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  auto [list, list_code] = curl(dir, {farm.url + "/api/jobs"});
  ASSERT_EQ(list_code, 200);
  EXPECT_EQ(nlohmann::json::parse(list)["running"], nlohmann::json::array({1})) << list;
  auto [cancelled, cancel_code] = curl(dir, {"-d", "", "-H", "Authorization: Bearer " + farm.token, farm.url + "/api/jobs/1/cancel"});
  ASSERT_EQ(cancel_code, 200) << cancelled;
  ASSERT_TRUE(wait_until([&] { return job_state(farm, 1) == "cancelled"; })) << slurp(dir / "farm0.log");
  EXPECT_FALSE(fs::exists(long_dir / "preview.png"));
  EXPECT_FALSE(fs::exists(long_dir / "preview.glb"));
  EXPECT_FALSE(fs::exists(long_dir / "checkpoint"));
  EXPECT_EQ(curl(dir, {farm.url + "/api/jobs/1/glb-version"}).first, "missing");
  EXPECT_EQ(curl(dir, {farm.url + "/api/jobs/1/glb"}).second, 404);
  stop_farm(farm, nodes, dir, "farm0.log");
}

// A farm killed -9 in the middle of a job, with another queued, and started again on the same
// folder and endpoint while its two nodes keep running: the job resumes from its checkpoint
// (its record says it ran twice), every job ends done, each ran every bundle index once (their
// ledgers, across both farm processes), and the long furnace is unbiased within 4 sd of its
// K-bundle chain average (0.0097 sqrt(1024 / K) 4; plain transport, random directions).
// No step races the clock: the nodes are stopped (SIGSTOP) once the long job has run bundles,
// and the kill waits for a checkpoint written after that; should the job have ended before the
// nodes stopped (a fast machine), a job 8 times longer is queued first and the same is done
// with it, until one is caught mid-run.
TEST(Farm, AKilledFarmResumesItsQueueAndRunsEveryJobOnce) {
  const fs::path dir = fresh_dir("sirad_farm_kill");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  std::map<int, uint64_t> bundles_of;  // every job submitted: its bundles
  auto submit = [&](const std::string& name, uint64_t bundles, int priority) {
    EXPECT_EQ(sirad_submit(dir, {"furnace", "--farm", farm.folder.string(), "--name", name, "--priority", std::to_string(priority),
                                 "--patches", "300", "--bundles", std::to_string(bundles), "--exchange-every", "16", "--mode", "sync",
                                 "--control-variate", "off", "--directions", "random", "--shots-per-bundle", "0", "--width", "8",
                                 "--height", "8"}),
              0)
        << slurp(dir / "submit.log");
    bundles_of[static_cast<int>(bundles_of.size()) + 1] = bundles;
  };
  uint64_t K = 8192;
  submit("long", K, 1);  // job 1
  submit("short", 256, 0);  // job 2
  int caught = 1;  // the long job the kill is to catch mid-run
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, farm.endpoint, "k", 2);
  auto job_dir = [&](int id) { return farm.folder / "jobs" / std::to_string(id); };
  for (int attempt = 0;; ++attempt) {
    ASSERT_LT(attempt, 6) << "no long job was caught running";
    ASSERT_TRUE(wait_until([&] {
      return job_state(farm, caught) == "done" || bundles_done(job_dir(caught) / "status.json") > 0;
    })) << slurp(dir / "farm0.log");
    for (auto& n : nodes) n->pause();
    if (job_state(farm, caught) != "done") break;
    for (auto& n : nodes) n->resume();  // it ended first: a longer one, run next
    K *= 8;
    submit(fmt::format("long{}", attempt + 1), K, 10 + attempt);
    caught = static_cast<int>(bundles_of.size());
  }
  // Stopped mid-run: a checkpoint written after that is what the next farm finds.
  ASSERT_TRUE(wait_until([&] { return fs::exists(job_dir(caught) / "checkpoint"); }));
  auto before = fs::last_write_time(job_dir(caught) / "checkpoint");
  ASSERT_TRUE(wait_until([&] { return fs::last_write_time(job_dir(caught) / "checkpoint") != before; }));
  farm.process->kill9();
  ASSERT_EQ(farm.process->wait(sirad::test::kHangS), 128 + SIGKILL);
  EXPECT_EQ(job_state(farm, caught), "running");
  FarmProcess again = start_farm(dir, farm.endpoint, 1);
  for (auto& n : nodes) n->resume();
  ASSERT_TRUE(wait_until([&] {
    for (const auto& [id, bundles] : bundles_of)
      if (job_state(again, id) != "done") return false;
    return true;
  })) << slurp(dir / "farm1.log");
  EXPECT_EQ(job_record(again, caught)["runs"], 2);
  for (const auto& [id, bundles] : bundles_of) expect_every_index_once(read_ledger(job_dir(id) / "ledger.csv"), bundles);
  const std::string name = job_record(again, caught)["name"];
  EXPECT_NEAR(furnace_mean(job_dir(caught) / (name + ".ply")), 2.0, 0.0097 * std::sqrt(1024.0 / bundles_of[caught]) * 4);
  stop_farm(again, nodes, dir, "farm1.log");
}

// The web page in a real browser: a farm with a finished Cornell job and its node, loaded by
// headless Chromium. Its DOM after the page's script ran lists the job (done), its node and
// its image's link; its screenshot shows the done badge (#2e7d32) and the job's image (the
// Cornell box's red wall: pixels of high red and low green and blue, which nothing else on the
// page has), and its 3D view draws the job's glb. Then, with a long job running, the page opens
// on it: its preview image and glb (once the farm has written them) and its node's traffic. Skipped, saying why, where Chromium is not
// installed (CI installs it).
TEST(Farm, ThePageShowsTheQueueInAHeadlessBrowser) {
  const std::string chromium = sirad::test::on_path("chromium");
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (deploy/install-deps.sh installs it)";
  const fs::path dir = fresh_dir("sirad_farm_page");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, farm.endpoint, "w", 1);
  ASSERT_EQ(sirad_submit(dir, {"cornell", "--farm", farm.folder.string(), "--name", "shown", "--patches", "500", "--bundles", "128",
                               "--width", "256", "--height", "256"}),
            0)
      << slurp(dir / "submit.log");
  ASSERT_TRUE(wait_until([&] { return job_state(farm, 1) == "done"; })) << slurp(dir / "farm0.log");
  const std::vector<std::string> browser = {chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                                            "--user-data-dir=" + (dir / "profile").string(), "--virtual-time-budget=8000",
                                            "--window-size=1100,900"};
  std::vector<std::string> dump = browser;
  dump.insert(dump.end(), {"--dump-dom", farm.url + "/"});
  Child dom(dump, dir / "dom.html");
  ASSERT_EQ(dom.wait(sirad::test::kHangS), 0) << slurp(dir / "dom.html");
  const std::string html = slurp(dir / "dom.html");
  EXPECT_NE(html.find("<td>shown</td>"), std::string::npos) << html;
  EXPECT_NE(html.find("state state-done"), std::string::npos) << html;
  EXPECT_NE(html.find("<td>w0</td>"), std::string::npos) << "the node table\n" << html;
  EXPECT_NE(html.find("/api/jobs/1/files/shown.png"), std::string::npos) << html;
  std::vector<std::string> shot = browser;
  shot.insert(shot.end(), {"--screenshot=" + (dir / "page.png").string(), farm.url + "/"});
  Child screenshot(shot, dir / "screenshot.log");
  ASSERT_EQ(screenshot.wait(sirad::test::kHangS), 0) << slurp(dir / "screenshot.log");
  int width = 0, height = 0;
  std::vector<unsigned char> rgb = sirad::test::read_png((dir / "page.png").string(), width, height);
  ASSERT_EQ(rgb.size(), static_cast<std::size_t>(width) * height * 3);
  std::size_t badge = 0;
  for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) {
    const int r = rgb[i], g = rgb[i + 1], b = rgb[i + 2];
    badge += std::abs(r - 0x2e) <= 3 && std::abs(g - 0x7d) <= 3 && std::abs(b - 0x32) <= 3;
  }
  EXPECT_GT(badge, 50u) << "no done badge in the screenshot";
  EXPECT_GT(red_wall_pixels(rgb), 500u) << "no image of the Cornell box in the screenshot";
  // Its 3D view (where sirad was built with three.js): framed in the page, following the job's
  // glb (its result's version), and drawn from it by the viewer in a browser of its own with a
  // software GL (200 x 200: Chromium's headless screenshots of 96 to 128 pixel windows show no
  // canvas at all). The Cornell box's lit red wall takes the same share of it as of the job's
  // image, from the same camera at the glb's exposure (measured 0.0835 and 0.0839); a wrong
  // camera, exposure or an unlit page is off by far more than 15 %, edge pixels by less.
  if (sirad::viewer_available()) {
    EXPECT_NE(html.find("/view?glb=/api/jobs/1/glb&amp;version=/api/jobs/1/glb-version"), std::string::npos) << html;
    EXPECT_EQ(curl(dir, {farm.url + "/api/jobs/1/glb-version"}).first.rfind("shown.glb-", 0), 0u);
    Child view({chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars",
                "--user-data-dir=" + (dir / "profile-view").string(), "--window-size=200,200", "--virtual-time-budget=30000",
                "--screenshot=" + (dir / "view.png").string(),
                farm.url + "/view?glb=/api/jobs/1/glb&version=/api/jobs/1/glb-version&probe=1"},
               dir / "view.log");
    ASSERT_EQ(view.wait(sirad::test::kHangS), 0) << slurp(dir / "view.log");
    auto red_share = [](const std::vector<unsigned char>& rgb) {
      return static_cast<double>(red_wall_pixels(rgb)) / static_cast<double>(std::max<std::size_t>(rgb.size() / 3, 1));
    };
    int iw = 0, ih = 0;
    const double in_view = red_share(sirad::test::read_png((dir / "view.png").string(), width, height));
    const double in_image = red_share(sirad::test::read_png((farm.folder / "jobs" / "1" / "shown.png").string(), iw, ih));
    std::printf("red wall: %.4f of the 3D view, %.4f of the job's image\n", in_view, in_image);
    EXPECT_GT(in_image, 0.05);
    EXPECT_NEAR(in_view / in_image, 1.0, 0.15) << "the job's 3D view does not show its lit red wall as its image does";
  }
  // A running job is the one the page opens on: its preview image and its node's traffic.
  ASSERT_EQ(sirad_submit(dir, {"cornell", "--farm", farm.folder.string(), "--name", "running", "--patches", "500", "--bundles",
                               "100000000", "--exchange-every", "8", "--width", "64", "--height", "64"}),
            0)
      << slurp(dir / "submit.log");
  ASSERT_TRUE(wait_until([&] {
    if (!fs::exists(farm.folder / "jobs" / "2" / "preview.png") || !fs::exists(farm.folder / "jobs" / "2" / "preview.glb")) return false;
    auto n = status_nodes(farm.folder / "jobs" / "2" / "status.json");
    return !n.empty() && n[0].bytes_in > 0;
  })) << slurp(dir / "farm0.log");
  Child dom2(dump, dir / "dom2.html");
  ASSERT_EQ(dom2.wait(sirad::test::kHangS), 0) << slurp(dir / "dom2.html");
  const std::string html2 = slurp(dir / "dom2.html");
  EXPECT_NE(html2.find("job 2: running (running)"), std::string::npos) << html2;
  EXPECT_NE(html2.find("preview at "), std::string::npos) << html2;
  EXPECT_NE(html2.find("/api/jobs/2/files/preview.png?at="), std::string::npos) << html2;
  EXPECT_NE(html2.find("iB</td>"), std::string::npos) << "no node traffic (KiB or more)\n" << html2;
  if (sirad::viewer_available()) {  // its 3D view follows the preview glb until the result's
    EXPECT_NE(html2.find("/view?glb=/api/jobs/2/glb&amp;version=/api/jobs/2/glb-version"), std::string::npos) << html2;
    EXPECT_EQ(curl(dir, {farm.url + "/api/jobs/2/glb-version"}).first.rfind("preview.glb-", 0), 0u);
  }
  stop_farm(farm, nodes, dir, "farm0.log");
}

// A job's JSON nested 200,000 levels deep (in a field the farm does not read) is refused by its
// depth (400), before it is parsed; a scene file submitted by `sirad submit` (its multipart form
// as the client writes it) is queued.
TEST(Farm, AJobNestedTooDeepIsRefusedAndASceneFileIsQueued) {
  const fs::path dir = fresh_dir("sirad_farm_deep");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  std::ofstream(dir / "deep.json") << R"({"name": "deep", "scene": "cornell", "priority": 0, "args": [], "x": )"
                                   << std::string(200000, '[') << std::string(200000, ']') << "}";
  auto [said, code] = curl(dir, {"-H", "Authorization: Bearer " + farm.token, "-F", "job=<" + (dir / "deep.json").string(),
                                 farm.url + "/api/jobs"});
  EXPECT_EQ(code, 400) << said;
  EXPECT_NE(said.find("job: JSON nested deeper than 64 levels"), std::string::npos) << said;
  EXPECT_EQ(sirad_submit(dir, {std::string(SIRAD_SOURCE_DIR) + "/scenes/cornell_box.obj", "--farm", farm.folder.string(), "--name",
                               "box", "--bundles", "16"}),
            0)
      << slurp(dir / "submit.log");
  EXPECT_EQ(job_state(farm, 1), "queued");
  std::vector<std::unique_ptr<Child>> nodes;
  stop_farm(farm, nodes, dir, "farm0.log");
}

// Clients that open connections and send their request slowly, or never, hold none of the HTTP
// server's threads (farm/http_guard.h). With 60 such connections open from one address (the
// server's pool has 8 threads; before the guard, 8 froze the page for as long as they stayed,
// and these 60 for 40 s of read timeouts), the page and the API answer, and when they have,
// every held connection is still open or was closed by the guard's head deadline with a 408
// (before the guard, the server's read timeout closed them without a word, and only then did
// the page answer): an order of events, not a time. A client's 65th connection is refused at
// once (503), and the held ones are closed at their head's deadline with 408 (waited for as
// events, within the suite's hang bound).
TEST(Farm, SlowClientsHoldNoneOfTheServersThreads) {
  const fs::path dir = fresh_dir("sirad_farm_slow");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  const int port = std::stoi(farm.url.substr(farm.url.rfind(':') + 1));
  auto connect_to_farm = [&] {
    const int s = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
    return s;
  };
  auto say = [](int s, const std::string& text) { EXPECT_EQ(::send(s, text.data(), text.size(), MSG_NOSIGNAL), ssize_t(text.size())); };
  // What the farm answers on `s` until it closes it (bounded by the suite's hang time).
  auto answer_on = [](int s) {
    std::string got;
    char buffer[4096];
    for (;;) {
      pollfd p{s, POLLIN, 0};
      if (::poll(&p, 1, sirad::test::kHangS * 1000) != 1) return got + "(no answer)";
      const ssize_t n = ::recv(s, buffer, sizeof buffer, 0);
      if (n <= 0) return got;
      got.append(buffer, static_cast<std::size_t>(n));
    }
  };
  std::vector<int> held;
  for (int i = 0; i < 60; ++i) {
    held.push_back(connect_to_farm());
    say(held.back(), i % 2 ? "GET /api/jobs HTTP/1.1\r\nHost: farm\r\nX-Slow: " : "");  // half a head, or nothing
  }
  auto [page, page_code] = curl(dir, {farm.url + "/"});
  EXPECT_EQ(page_code, 200) << page;
  auto [jobs, jobs_code] = curl(dir, {farm.url + "/api/jobs"});
  EXPECT_EQ(jobs_code, 200) << jobs;
  std::vector<std::string> answered(held.size());
  for (std::size_t i = 0; i < held.size(); ++i) {
    pollfd p{held[i], POLLIN, 0};
    if (::poll(&p, 1, 0) != 0) answered[i] = answer_on(held[i]);  // already: only the guard's 408 may have come
  }
  for (std::size_t i = 0; i < held.size(); ++i) {  // each closed by the guard at its head's deadline, and so counted off
    if (answered[i].empty()) answered[i] = answer_on(held[i]);
    EXPECT_EQ(answered[i].rfind("HTTP/1.1 408", 0), 0u) << "held connection " << i << ": " << answered[i];
    ::close(held[i]);
  }
  // An address's bound: 64 connections opened now (the guard accepts in order, so it counts
  // them before the probe; the curls' may still count, which only reaches the bound sooner).
  held.clear();
  while (held.size() < sirad::cli::HttpGuard::kPerClient) held.push_back(connect_to_farm());
  const int probe = connect_to_farm();
  say(probe, "GET /api/jobs HTTP/1.1\r\nHost: farm\r\n\r\n");
  EXPECT_EQ(answer_on(probe).rfind("HTTP/1.1 503", 0), 0u);
  ::close(probe);
  for (int s : held) {  // 408 at the deadline (or 503, had the curls' connections still counted)
    const std::string a = answer_on(s);
    EXPECT_TRUE(a.rfind("HTTP/1.1 408", 0) == 0 || a.rfind("HTTP/1.1 503", 0) == 0) << a;
    ::close(s);
  }
  std::vector<std::unique_ptr<Child>> nodes;
  stop_farm(farm, nodes, dir, "farm0.log");
}

// A poison job: its camera's eye 1e20 away, which aborted a node in Embree and then the farm,
// rendering the tile itself, again after every restart. Now the job fails at its start with
// the reason, the farm and its node stay up, and the next job runs on that node. So does a job
// whose --max-edge would mesh the scene to 34 million patches (the farm takes 2^22): refused
// before the mesh is made, where the farm's memory once held whatever the flags asked for.
TEST(Farm, AJobWhoseCameraNoRayCanStartFromFailsAndTheFarmGoesOn) {
  const fs::path dir = fresh_dir("sirad_farm_poison");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  auto submit = [&](std::vector<std::string> args) { EXPECT_EQ(sirad_submit(dir, std::move(args)), 0) << slurp(dir / "submit.log"); };
  submit({"cornell", "--farm", farm.folder.string(), "--name", "far", "--priority", "1", "--patches", "200", "--bundles", "16",
          "--width", "16", "--height", "16", "--final-gather", "1", "--camera", "eye 1e20 0 0 look 0 0 0 up 0 1 0 fov 60"});
  submit({"cornell", "--farm", farm.folder.string(), "--name", "huge", "--priority", "1", "--max-edge", "0.5", "--bundles", "16"});
  submit({"cornell", "--farm", farm.folder.string(), "--name", "next", "--patches", "200", "--bundles", "16", "--width", "16",
          "--height", "16", "--final-gather", "1"});
  std::vector<std::unique_ptr<Child>> nodes = insecure_nodes(dir, farm.endpoint, "p", 1);
  ASSERT_TRUE(wait_until([&] { return job_state(farm, 3) == "done" || job_state(farm, 3) == "failed"; })) << slurp(dir / "farm0.log");
  EXPECT_EQ(job_state(farm, 1), "failed");
  EXPECT_NE(job_record(farm, 1)["error"].get<std::string>().find("the camera's eye is 1e+20 from the scene's centre"), std::string::npos)
      << job_record(farm, 1);
  EXPECT_EQ(job_state(farm, 2), "failed");
  EXPECT_NE(job_record(farm, 2)["error"].get<std::string>().find("patches, more than the 4194304 allowed"), std::string::npos)
      << job_record(farm, 2);
  EXPECT_EQ(job_state(farm, 3), "done") << job_record(farm, 3);
  EXPECT_TRUE(fs::exists(farm.folder / "jobs" / "3" / "next.exr"));
  // What ran is the job file's run, every setting spelled out as the table writes it.
  const nlohmann::json run = job_record(farm, 3)["run"];
  EXPECT_EQ(run["settings"]["patches"], "200") << run;
  EXPECT_EQ(run["settings"]["shots-per-bundle"], "0.25") << run;
  EXPECT_EQ(run["output"], nlohmann::json({"--width", "16", "--height", "16", "--final-gather", "1"})) << run;
  stop_farm(farm, nodes, dir, "farm0.log");
}

// A job's spec as the API takes it: each field of its kind, checked before it is converted,
// and refused with its name where it is not (priorities of 1e300, 2^31 or 2^63 wrapped to
// -2147483648, 0 or 1, and 1.5 became 1; a list of numbers as args answered nlohmann's raw
// "type_error.302"); flags that ask for help, an image too large for memory and the name
// `preview` (its PNG would be the farm's preview) are refused when submitted, not when run.
TEST(Farm, AJobSpecOfTheWrongKindIsRefusedWithItsReason) {
  const fs::path dir = fresh_dir("sirad_farm_spec");
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  auto submit = [&](const std::string& spec) {
    std::ofstream(dir / "spec.json") << spec;
    return curl(dir, {"-H", "Authorization: Bearer " + farm.token, "-F", "job=<" + (dir / "spec.json").string(), farm.url + "/api/jobs"});
  };
  const std::vector<std::pair<std::string, std::string>> refused = {
      {R"({"name": "a", "scene": "cornell", "priority": 1e300})", "'priority' is a whole number within +-1000000"},
      {R"({"name": "a", "scene": "cornell", "priority": 2147483648})", "'priority' is a whole number"},
      {R"({"name": "a", "scene": "cornell", "priority": 9223372036854775808})", "'priority' is a whole number"},
      {R"({"name": "a", "scene": "cornell", "priority": 1.5})", "'priority' is a whole number"},
      {R"({"name": "a", "scene": "cornell", "priority": "3"})", "'priority' is a whole number"},
      {R"({"name": "a", "scene": "cornell", "args": [1, 2]})", "'args' is not a list of strings"},
      {R"({"name": "a", "scene": "cornell", "args": "--bundles 4"})", "'args' is not a list of strings"},
      {R"({"name": 7, "scene": "cornell"})", "'name' is not a string"},
      {R"({"name": "a", "scene": "cornell", "args": ["--help"]})", "a job cannot ask for help"},
      {R"({"name": "a", "scene": "cornell", "args": ["--width", "16384", "--height", "16384"]})", "more than 33554432 pixels"},
      {R"({"name": "preview", "scene": "cornell"})", "job name 'preview'"},
      {R"({"name": "a", "scene": "cornell", "args": ["--patches", "5000000"]})", "--patches 5000000: a farm takes jobs of at most 4194304 patches"}};
  for (const auto& [spec, why] : refused) {
    auto [said, code] = submit(spec);
    EXPECT_EQ(code, 400) << spec << ": " << said;
    EXPECT_NE(said.find(why), std::string::npos) << spec << ": " << said;
    EXPECT_EQ(said.find("json.exception"), std::string::npos) << said;
  }
  auto [said, code] = submit(R"({"name": "ok", "scene": "cornell", "priority": -1000000, "args": ["--bundles", "4"]})");
  EXPECT_EQ(code, 201) << said;
  EXPECT_EQ(nlohmann::json::parse(said)["priority"], -1000000);
  EXPECT_EQ(nlohmann::json::parse(said)["settings"]["bundles"], "4") << said;
  std::vector<std::unique_ptr<Child>> nodes;
  stop_farm(farm, nodes, dir, "farm0.log");
}

// The job list comes in pages (the page polls it every second; 20,000 jobs made each poll
// 4.5 MB): the newest 200 unless asked, `limit` and `before` for others, with the count of
// older jobs and of all; nonsense paging is a 400.
TEST(Farm, TheJobListComesInPages) {
  const fs::path dir = fresh_dir("sirad_farm_pages");
  {
    sirad::cluster::JobStore store((dir / "farm").string(), 0);
    for (int i = 0; i < 250; ++i) store.submit(fmt::format("j{}", i), "cornell", "", {}, sirad::cluster::JobRun{}, 0, i);
  }
  FarmProcess farm = start_farm(dir, "tcp://127.0.0.1:*", 0);
  auto ids = [](const std::string& text) {
    std::vector<uint64_t> out;
    const nlohmann::json body = nlohmann::json::parse(text);
    for (const auto& j : body["jobs"]) out.push_back(j["id"].get<uint64_t>());
    return out;
  };
  auto [first, code] = curl(dir, {farm.url + "/api/jobs"});
  ASSERT_EQ(code, 200) << first;
  std::vector<uint64_t> page = ids(first);
  ASSERT_EQ(page.size(), 200u);
  EXPECT_EQ(page.front(), 51u);
  EXPECT_EQ(page.back(), 250u);
  EXPECT_EQ(nlohmann::json::parse(first)["older"], 50);
  EXPECT_EQ(nlohmann::json::parse(first)["total"], 250);
  auto [second, code2] = curl(dir, {farm.url + "/api/jobs?limit=10&before=51"});
  ASSERT_EQ(code2, 200) << second;
  EXPECT_EQ(ids(second), (std::vector<uint64_t>{41, 42, 43, 44, 45, 46, 47, 48, 49, 50}));
  EXPECT_EQ(nlohmann::json::parse(second)["older"], 40);
  for (const char* bad : {"?limit=0", "?limit=1001", "?limit=x", "?before=-1", "?limit=99999999999999999999"})
    EXPECT_EQ(curl(dir, {farm.url + "/api/jobs" + bad}).second, 400) << bad;
  std::vector<std::unique_ptr<Child>> nodes;
  stop_farm(farm, nodes, dir, "farm0.log");
}

}  // namespace
