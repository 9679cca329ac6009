// sirad tests: the coordinator's checkpoint (cluster/checkpoint.h): a policy's state survives
// the file, a resumed policy carries on from it, and a damaged file is one clear error.
#include <filesystem>
#include <fstream>
#include <cstring>
#include <limits>

#include <functional>
#include <iterator>

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "cluster/checkpoint.h"
#include "util/error.h"

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
  Orders o = p.next_work();  // node 0: grants 0 and 1, node 1: 2 and 3 (8 bundles each)
  p.take_result(0, o.grants[0].id, o.grants[0].ranges, {chunk(0, 2.0, 8), chunk(1, 3.0, 8)}, 0.05);
  p.take_result(1, o.grants[2].id, o.grants[2].ranges, {chunk(0, 4.0, 8)}, 0);
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
    for (const GrantOrder& g : q.next_work().grants) {
      for (const Range& r : g.ranges) granted += r.size();
      q.take_result(n, g.id, g.ranges, {}, 0);
    }
  EXPECT_EQ(granted, 48u);
  EXPECT_EQ(q.ledger().done_count(), 64u);
  EXPECT_TRUE(q.ending());
}

// Damaged or foreign files are refused with the file's name and what is wrong.
TEST(Checkpoint, ADamagedFileIsOneClearError) {
  Policy p = make(64, 1);
  p.ready(0);
  Orders o = p.next_work();
  p.take_result(0, o.grants[0].id, o.grants[0].ranges, {chunk(0, 2.0, 8)}, 0);
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
  c.set_version(kCheckpointVersion + 1);
  expect_refused(c, fmt::format("version {}", kCheckpointVersion + 1));
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

namespace sirad::cluster {
namespace {

std::string bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// Every single-bit flip of a real checkpoint (the golden run's, tests/data/golden) is refused
// with one error naming the file: the header's magic and version are compared whole, a flip in
// the stored checksum no longer matches, and a flip in the payload leaves its XXH3-64 unchanged
// with probability 2^-64 for a hash that mixes like a random function (61,600 flips: 3e-15).
// The file is fixed, so the outcome is too. The unflipped file reads.
TEST(Checkpoint, EverySingleBitFlipIsRefused) {
  const fs::path golden = fs::path(SIRAD_SOURCE_DIR) / "tests/data/golden/resume.ckpt";
  const std::string good = bytes_of(golden);
  ASSERT_GT(good.size(), 1000u);
  const fs::path dir = fs::is_directory("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();  // 61,600 writes
  const fs::path file = dir / fmt::format("sirad_checkpoint_flip_{}", ::getpid());
  std::ofstream(file, std::ios::binary) << good;
  EXPECT_NO_THROW(read_checkpoint(file.string()));
  std::size_t accepted = 0, unclear = 0;
  std::string bad = good;
  for (std::size_t byte = 0; byte < good.size(); ++byte)
    for (int bit = 0; bit < 8; ++bit) {
      bad[byte] = static_cast<char>(good[byte] ^ (1 << bit));
      {
        std::ofstream out(file, std::ios::binary | std::ios::trunc);
        out << bad;
      }
      try {
        read_checkpoint(file.string());
        ++accepted;
      } catch (const Error& e) {
        unclear += std::string(e.what()).rfind(file.string() + ": ", 0) != 0;
      }
      bad[byte] = good[byte];
    }
  fs::remove(file);
  EXPECT_EQ(accepted, 0u) << "of " << 8 * good.size() << " single-bit flips";
  EXPECT_EQ(unclear, 0u);
}

// A crafted checkpoint (a valid checksum over values no run has) is refused field by field,
// as the wire decoder refuses a message.
TEST(Checkpoint, CraftedValuesOutOfRangeAreRefused) {
  const fs::path golden = fs::path(SIRAD_SOURCE_DIR) / "tests/data/golden/resume.ckpt";
  const wire::Checkpoint good = read_checkpoint(golden.string());
  ASSERT_GT(good.nodes_size(), 0);
  const fs::path file = fs::temp_directory_path() / fmt::format("sirad_checkpoint_crafted_{}", ::getpid());
  auto refused = [&](const std::function<void(wire::Checkpoint&)>& edit, const std::string& what) {
    wire::Checkpoint c = good;
    edit(c);
    write_checkpoint(file.string(), c);
    try {
      read_checkpoint(file.string());
      ADD_FAILURE() << "accepted: " << what;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  refused([](wire::Checkpoint& c) { c.mutable_nodes(0)->set_counts(0, 1'000'000'000'000'000ull); }, "more than its");
  refused([](wire::Checkpoint& c) { c.mutable_nodes(0)->set_bundles(1'000'000'000'000'000ull); }, "bundles");
  refused([](wire::Checkpoint& c) { c.mutable_run()->set_grid(100000); }, "grid 100000");
  refused([](wire::Checkpoint& c) { c.mutable_run()->set_burn_in(std::numeric_limits<int32_t>::max()); }, "burn-in");
  refused([](wire::Checkpoint& c) { c.set_elapsed_s(1e300); }, "elapsed time");
  refused([](wire::Checkpoint& c) { c.set_time_limit_s(std::numeric_limits<double>::infinity()); }, "time limit");
  refused([](wire::Checkpoint& c) { c.mutable_nodes(0)->set_busy_s(-1); }, "busy");
  refused([](wire::Checkpoint& c) { c.mutable_nodes(0)->set_error(std::numeric_limits<double>::quiet_NaN()); }, "error estimate");
  refused([](wire::Checkpoint& c) { c.mutable_run()->set_topology("staz"); }, "topology 'staz'");
  refused([](wire::Checkpoint& c) { c.mutable_run()->set_target_patches(uint64_t{1} << 40); }, "target patches");
  refused([](wire::Checkpoint& c) { c.mutable_nodes(0)->set_name(std::string(100000, 'x')); }, "over its size");
  fs::remove(file);
}

// The reader opens only regular files, never blocking on a FIFO or reading a device for ever.
TEST(Checkpoint, DevicesAndFifosAreRefusedAtOnce) {
  for (const char* path : {"/dev/zero", "/dev/urandom"}) {
    try {
      read_checkpoint(path);
      ADD_FAILURE() << "read " << path;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
    }
  }
  const fs::path fifo = fs::temp_directory_path() / fmt::format("sirad_checkpoint_fifo_{}", ::getpid());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THROW(read_checkpoint(fifo.string()), Error);  // would block for ever in a plain open
  fs::remove(fifo);
  EXPECT_THROW(read_checkpoint(fs::temp_directory_path().string()), Error);
}

}  // namespace
}  // namespace sirad::cluster
