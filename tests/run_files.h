// sirad tests: a run's processes (a coordinator and its nodes over loopback TCP, insecure node
// processes) and what they write, as the process tests read it: the PLY's per-face radiosity,
// the ledger, the status JSON.
#pragma once
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glm/vec3.hpp>
#include <gtest/gtest.h>

#include "cluster/status.h"
#include "tests/process_util.h"

namespace sirad::test {

// The per-face radiosity of a PLY written by sirad (after the header: vertices of three floats
// and three colour bytes, then per face: uchar 3, three ints, nine floats: radiosity,
// reflectance, emission).
inline std::vector<glm::vec3> ply_radiosity(const fs::path& path) {
  std::string ply = slurp(path);
  auto header_end = ply.find("end_header\n") + 11;
  auto count_of = [&](const std::string& element) {
    auto at = ply.find("element " + element + " ");
    return std::stoull(ply.substr(at + 9 + element.size()));
  };
  uint64_t vertices = count_of("vertex"), faces = count_of("face");
  const char* p = ply.data() + header_end + vertices * 15;
  std::vector<glm::vec3> out(faces);
  for (uint64_t f = 0; f < faces; ++f) {
    std::memcpy(&out[f], p + 1 + 12, 12);
    p += 1 + 12 + 36;
  }
  return out;
}

// The ledger a coordinator wrote with --ledger: one row per range a node ran.
struct LedgerRow {
  uint32_t node = 0;
  std::string name;
  uint64_t first = 0, last = 0;
};

inline std::vector<LedgerRow> read_ledger(const fs::path& path) {
  std::istringstream in(slurp(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "node,name,first,last");
  std::vector<LedgerRow> rows;
  while (std::getline(in, line)) {
    LedgerRow r;
    auto q1 = line.find(",\""), q2 = line.rfind("\",");
    r.node = static_cast<uint32_t>(std::stoul(line.substr(0, q1)));
    r.name = line.substr(q1 + 2, q2 - q1 - 2);
    std::sscanf(line.c_str() + q2 + 2, "%lu,%lu", &r.first, &r.last);
    rows.push_back(r);
  }
  return rows;
}

// Every index 0..K-1 appears in exactly one ledger range: nothing counted twice, nothing lost.
inline void expect_every_index_once(const std::vector<LedgerRow>& rows, uint64_t bundles) {
  std::vector<int> seen(bundles, 0);
  for (const LedgerRow& r : rows) {
    ASSERT_LE(r.first, r.last);
    ASSERT_LE(r.last, bundles);
    for (uint64_t k = r.first; k < r.last; ++k) ++seen[k];
  }
  for (uint64_t k = 0; k < bundles; ++k) ASSERT_EQ(seen[k], 1) << "bundle index " << k;
}

// `count` node processes over TCP without CURVE, named PREFIX0, PREFIX1, ..., each logging to
// dir/nodeI.log.
inline std::vector<std::unique_ptr<Child>> insecure_nodes(const fs::path& dir, const std::string& endpoint, const std::string& prefix,
                                                   int count) {
  std::vector<std::unique_ptr<Child>> nodes;
  for (int i = 0; i < count; ++i)
    nodes.push_back(std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--insecure", "--name", fmt::format("{}{}", prefix, i)},
        dir / fmt::format("node{}.log", i)));
  return nodes;
}

// "bundles_done" of a status JSON (0 while there is none).
inline uint64_t bundles_done(const fs::path& status) {
  try {
    return sirad::cluster::read_status(status.string()).bundles_done;
  } catch (const std::exception&) {
    return 0;
  }
}

// The nodes of a --status-json file (none while it does not exist yet).
inline std::vector<sirad::cluster::Status::Node> status_nodes(const fs::path& status) {
  try {
    return sirad::cluster::read_status(status.string()).nodes;
  } catch (const std::exception&) {
    return {};
  }
}

// A coordinator process and `nodes` node processes over loopback TCP on a system-chosen port;
// returns the coordinator's exit status (its log and outputs are in `dir`).
inline int run_processes(const fs::path& dir, int nodes, std::vector<std::string> coordinator_args) {
  std::vector<std::string> args = {SIRAD_COORDINATOR_BINARY};
  args.insert(args.end(), coordinator_args.begin(), coordinator_args.end());
  for (std::string a : std::vector<std::string>{"--listen", "tcp://127.0.0.1:*", "--insecure", "--endpoint-file",
                                                (dir / "endpoint").string(), "--min-nodes", fmt::format("{}", nodes),
                                                "--timeout", sirad::test::kHangTimeout, "-q"})
    args.push_back(a);
  Child coordinator(args, dir / "coordinator.log");
  if (!coordinator.started()) return -1;
  if (!sirad::test::wait_for_file(dir / "endpoint", coordinator)) return -1;
  std::string endpoint = slurp(dir / "endpoint");
  std::vector<std::unique_ptr<Child>> children;
  for (int i = 0; i < nodes; ++i)
    children.push_back(std::make_unique<Child>(
        std::vector<std::string>{SIRAD_NODE_BINARY, "--connect", endpoint, "--insecure", "--name", fmt::format("p{}", i)},
        dir / fmt::format("node{}.log", i)));
  int status = coordinator.wait(sirad::test::kHangS);
  for (auto& n : children) {
    n->terminate();
    if (n->wait(sirad::test::kHangS) != 0) status = status == 0 ? -2 : status;
  }
  return status;
}

}  // namespace sirad::test
