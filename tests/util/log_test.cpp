// sirad tests: the operator's log (util/log.h) and what the programs log with it: JSON lines
// for collectors, a node that says what it does, and a refused key made visible on the node.
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/process_util.h"
#include "util/error.h"
#include "util/log.h"

namespace fs = std::filesystem;
using sirad::test::Child;
using sirad::test::slurp;
using sirad::test::wait_until;

namespace sirad::logging {
namespace {

// A JSON line: time in UTC with milliseconds, level, who, message, then the fields; a field
// cannot replace the four, and bytes that are not UTF-8 (a peer's name) are replaced, never
// a broken line.
TEST(OperatorLog, JsonLinesCarryTheFieldsAndNeverBreak) {
  std::string line = json_line(1764000000.25, Level::warn, "sirad-node box-3", "coordinator silent",
                               {{"event", "left"}, {"seconds", 3.5}, {"level", "forged"}});
  nlohmann::json j = nlohmann::json::parse(line);
  EXPECT_EQ(j["time"], "2025-11-24T16:00:00.250Z");
  EXPECT_EQ(j["level"], "warn");
  EXPECT_EQ(j["who"], "sirad-node box-3");
  EXPECT_EQ(j["message"], "coordinator silent");
  EXPECT_EQ(j["event"], "left");
  EXPECT_EQ(j["seconds"], 3.5);
  EXPECT_EQ(line.find('\n'), std::string::npos);
  std::string odd = json_line(0, Level::info, "sirad-node \xff\xfe", "a\nb\x1b[2J", {});
  EXPECT_EQ(odd.find('\n'), std::string::npos) << odd;
  nlohmann::json o = nlohmann::json::parse(odd);  // throws if the line is not JSON
  EXPECT_EQ(o["message"], "a\nb\x1b[2J");
}

TEST(OperatorLog, LevelsAndFormatsAreNamedOrRefused) {
  EXPECT_EQ(parse_level("debug", "--log-level"), Level::debug);
  EXPECT_EQ(parse_format("json", "--log-format"), Format::json);
  EXPECT_THROW(parse_level("verbose", "--log-level"), Error);
  try {
    parse_format("xml", "--log-format");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "--log-format: 'xml' is not a log format (text, json)");
  }
}

// A coordinator and a node over loopback TCP, the node logging JSON at debug level: every
// line of its log is a JSON object with time, level, who and message, and the events of its
// run are there in order: start (its device), joined (the run), ready (its speed), a grant per
// grant at debug level, done (its bundles), left (why: the signal that stopped it).
TEST(OperatorLog, ANodeSaysWhatItDoesInJson) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_log_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  Child coordinator({SIRAD_COORDINATOR_BINARY, "furnace", "--listen", "tcp://127.0.0.1:*", "--insecure", "--endpoint-file",
                     (dir / "endpoint").string(), "--bundles", "64", "--patches", "200", "--min-nodes", "1",
                     "--exchange-every", "16", "--out", (dir / "furnace").string(), "--width", "8", "--height", "8",
                     "--log-format", "json", "--timeout", sirad::test::kHangTimeout, "-q"},
                    dir / "coordinator.log");
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  Child node({SIRAD_NODE_BINARY, "--connect", slurp(dir / "endpoint"), "--insecure", "--name", "n0", "--log-format", "json",
              "--log-level", "debug"},
             dir / "node.log");
  ASSERT_EQ(coordinator.wait(sirad::test::kHangS), 0) << slurp(dir / "coordinator.log");
  // The node has sent its FINAL (the coordinator ended): its "done" line is written first.
  ASSERT_TRUE(wait_until([&] { return slurp(dir / "node.log").find("\"done\"") != std::string::npos; })) << slurp(dir / "node.log");
  node.terminate();
  ASSERT_EQ(node.wait(sirad::test::kHangS), 0);
  std::vector<std::string> events;
  uint64_t granted = 0;
  std::istringstream lines(slurp(dir / "node.log"));
  for (std::string line; std::getline(lines, line);) {
    nlohmann::json j;
    ASSERT_NO_THROW(j = nlohmann::json::parse(line)) << "not a JSON line: " << line;
    for (const char* key : {"time", "level", "who", "message"}) EXPECT_TRUE(j.contains(key)) << line;
    if (!j.contains("event")) continue;
    events.push_back(j["event"]);
    if (j["event"] == "grant") granted += j["bundles"].get<uint64_t>();
    if (j["event"] == "start") {
      EXPECT_FALSE(j["device"].get<std::string>().empty()) << line;
    }
    if (j["event"] == "ready") {
      EXPECT_GT(j["ms_per_bundle"].get<double>(), 0) << line;
    }
    if (j["event"] == "done") {
      EXPECT_EQ(j["bundles"], 64) << line;
    }
    if (j["event"] == "left") {
      EXPECT_EQ(j["why"], "signal") << line;
    }
  }
  EXPECT_EQ(granted, 64u);
  std::vector<std::string> order;
  for (const std::string& e : events)
    if (e != "grant" && e != "insecure" && (order.empty() || order.back() != e)) order.push_back(e);
  EXPECT_EQ(order, (std::vector<std::string>{"start", "joined", "ready", "done", "left"})) << slurp(dir / "node.log");
  // The coordinator's lines are JSON too, its join and ready lines naming the node.
  std::string clog = slurp(dir / "coordinator.log");
  EXPECT_NE(clog.find("\"event\":\"joined\""), std::string::npos) << clog;
  EXPECT_NE(clog.find("\"peer\":\"n0\""), std::string::npos) << clog;
  if (!HasFailure()) fs::remove_all(dir);
}

// A node whose key is not in the coordinator's allow list hears nothing at all (CURVE refuses
// its handshake); it says so, naming the likely cause, once the silence has lasted, and the
// coordinator's log names the refused key. The test waits for both lines.
TEST(OperatorLog, ARefusedKeyIsVisibleOnTheNode) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_refused_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_FALSE(sirad::test::keygen(SIRAD_BINARY, dir, "coordinator").empty());
  std::string admitted = sirad::test::keygen(SIRAD_BINARY, dir, "admitted");
  ASSERT_FALSE(sirad::test::keygen(SIRAD_BINARY, dir, "stranger").empty());
  std::ofstream(dir / "allow") << admitted << "\n";
  Child coordinator({SIRAD_COORDINATOR_BINARY, "furnace", "--listen", "tcp://127.0.0.1:*", "--curve-secret",
                     (dir / "coordinator.key_secret").string(), "--allow", (dir / "allow").string(), "--endpoint-file",
                     (dir / "endpoint").string(), "--bundles", "64", "--patches", "200", "--timeout", sirad::test::kHangTimeout,
                     "-q"},
                    dir / "coordinator.log");
  ASSERT_TRUE(sirad::test::wait_for_file(dir / "endpoint", coordinator)) << slurp(dir / "coordinator.log");
  Child node({SIRAD_NODE_BINARY, "--connect", slurp(dir / "endpoint"), "--name", "stranger", "--curve-secret",
              (dir / "stranger.key_secret").string(), "--server-key", (dir / "coordinator.key").string()},
             dir / "node.log");
  EXPECT_TRUE(wait_until([&] { return slurp(dir / "node.log").find("is this node's key in its allow list") != std::string::npos; }))
      << slurp(dir / "node.log");
  EXPECT_TRUE(wait_until([&] { return slurp(dir / "coordinator.log").find("is not in the allow list") != std::string::npos; }))
      << slurp(dir / "coordinator.log");
  node.terminate();
  EXPECT_EQ(node.wait(sirad::test::kHangS), 0);
  coordinator.terminate();
  coordinator.wait(sirad::test::kHangS);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace sirad::logging
