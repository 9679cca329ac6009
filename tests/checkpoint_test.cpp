// sirad tests: the coordinator's checkpoint (cluster/checkpoint.h): a policy's state survives
// the file, a resumed policy carries on from it, and a damaged file is one clear error.
#include <filesystem>
#include <fstream>
#include <cstring>
#include <limits>

#include <unistd.h>

#include <gtest/gtest.h>

#include "cluster/checkpoint.h"
#include "core/error.h"

namespace sirad::cluster {
namespace {

namespace fs = std::filesystem;

Policy make(uint64_t bundles, uint32_t nodes) {
  PolicyConfig c{.bundles = bundles, .exchange_every = 8, .mode = Mode::async, .min_nodes = nodes, .balance = false};
  Policy p(c, chunk_starts(64, 4), std::vector<double>(64, 1.0));
  for (uint32_t n = 0; n < nodes; ++n) p.join();
  return p;
}

ChunkState chunk(uint32_t c, double value, uint64_t count) {
  return {c, std::vector<double>(48, value * static_cast<double>(count)), count};
}

wire::Checkpoint checkpoint_of(const Policy& p) {
  wire::Checkpoint c;
  c.set_magic(kCheckpointMagic);
  c.set_version(kCheckpointVersion);
  wire::Run* run = c.mutable_run();
  run->set_bundles(p.ledger().bundles());
  run->set_patches(64);
  for (uint32_t s : {0, 16, 32, 48}) run->add_chunk_starts(s);
  run->set_topology("star");
  run->set_mode("async");
  run->set_rule("chain");
  put_snapshot(c, p.snapshot());
  return c;
}

// Two nodes run some grants; the policy goes through a checkpoint file into a fresh one, which
// has the same estimate, the same ledger record (the outstanding grants back in the budget),
// its nodes dead, and carries on: new nodes get exactly the bundles not done, and the run ends
// with every index once.
TEST(Checkpoint, APolicyResumesFromItsFile) {
  Policy p = make(64, 2);
  p.ready(0);
  p.ready(1);
  Orders o = p.schedule();  // node 0: grants 0 and 1, node 1: 2 and 3 (8 bundles each)
  p.report(0, o.grants[0].id, o.grants[0].ranges, {chunk(0, 2.0, 8), chunk(1, 3.0, 8)}, 0.05);
  p.report(1, o.grants[2].id, o.grants[2].ranges, {chunk(0, 4.0, 8)}, 0);
  fs::path file = fs::temp_directory_path() / fmt::format("sirad_checkpoint_{}", ::getpid());
  write_checkpoint(file.string(), checkpoint_of(p));
  wire::Checkpoint c = read_checkpoint(file.string());
  fs::remove(file);

  Policy q = make(64, 0);
  q.restore(snapshot_of(c));
  EXPECT_EQ(q.nodes(), 2u);
  EXPECT_TRUE(q.node(0).dead && q.node(1).dead);
  EXPECT_EQ(q.node(0).bundles, 8u);
  EXPECT_DOUBLE_EQ(q.node(0).error, 0.05);
  EXPECT_EQ(q.radiosity(), p.radiosity());
  EXPECT_EQ(q.ledger().done_count(), 16u);
  EXPECT_EQ(q.ledger().done_by(1), p.ledger().done_by(1));
  EXPECT_EQ(q.ledger().available(), 48u) << "the outstanding grants of the stopped coordinator's nodes are free";
  uint32_t n = q.join();
  q.ready(n);
  uint64_t granted = 0;
  for (int round = 0; round < 20 && !q.ending(); ++round)
    for (const GrantOrder& g : q.schedule().grants) {
      for (const Range& r : g.ranges) granted += r.size();
      q.report(n, g.id, g.ranges, {}, 0);
    }
  EXPECT_EQ(granted, 48u);
  EXPECT_EQ(q.ledger().done_count(), 64u);
  EXPECT_TRUE(q.ending());
}

// Damaged or foreign files are refused with the file's name and what is wrong.
TEST(Checkpoint, ADamagedFileIsOneClearError) {
  Policy p = make(64, 1);
  p.ready(0);
  Orders o = p.schedule();
  p.report(0, o.grants[0].id, o.grants[0].ranges, {chunk(0, 2.0, 8)}, 0);
  const wire::Checkpoint good = checkpoint_of(p);
  fs::path file = fs::temp_directory_path() / fmt::format("sirad_checkpoint_bad_{}", ::getpid());
  auto expect_refused = [&](const wire::Checkpoint& c, const std::string& what) {
    write_checkpoint(file.string(), c);
    try {
      read_checkpoint(file.string());
      ADD_FAILURE() << "accepted: " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  wire::Checkpoint c = good;
  c.set_magic("something else");
  expect_refused(c, "not a sirad checkpoint");
  c = good;
  c.set_version(2);
  expect_refused(c, "version 2");
  c = good;
  c.mutable_nodes(0)->mutable_sums()->resize(100);
  expect_refused(c, "bytes of sums");
  c = good;
  wire::Range* twice = c.mutable_nodes(0)->add_done();
  twice->set_first(0);
  twice->set_last(4);
  expect_refused(c, "done twice");
  c = good;
  std::string sums = c.nodes(0).sums();
  double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(sums.data(), &nan, sizeof nan);
  c.mutable_nodes(0)->set_sums(sums);
  expect_refused(c, "nan");
  c = good;
  c.mutable_run()->set_chunk_starts(2, 8);
  expect_refused(c, "out of order");
  std::ofstream(file) << "not protobuf at all \xff\xff";
  EXPECT_THROW(read_checkpoint(file.string()), Error);
  fs::remove(file);
  EXPECT_THROW(read_checkpoint(file.string()), Error);
}

}  // namespace
}  // namespace sirad::cluster
