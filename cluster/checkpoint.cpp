// sirad: the coordinator's checkpoint file (see checkpoint.h).
#include "cluster/checkpoint.h"

#include <algorithm>
#include <cmath>
#include <string_view>

#include <xxhash.h>

#include "proto/transport.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::cluster {

namespace {

// The file: kFileMagic, the format version (u32), the XXH3-64 of the payload (u64), then the
// payload, a serialised wire::Checkpoint; integers little-endian.
constexpr std::string_view kFileMagic = "SIRADCKP";
constexpr std::size_t kHeaderBytes = kFileMagic.size() + 4 + 8;
// The largest checkpoint read: 24 bytes per patch per node, so this holds, for example, a
// million patches on 700 nodes.
constexpr std::size_t kMaxCheckpointBytes = std::size_t{16} << 30;
constexpr std::size_t kMaxCheckpointText = 4096;  // a name, a reason, how the run ended
constexpr std::size_t kMaxCheckpointNodes = 1 << 16;

template <typename T>
void put_le(std::string& out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
template <typename T>
T get_le(std::string_view in) {
  T v = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(static_cast<unsigned char>(in[i])) << (8 * i);
  return v;
}

}  // namespace

std::string frame_checkpoint(std::string_view payload) {
  std::string bytes(kFileMagic);
  put_le<uint32_t>(bytes, kCheckpointVersion);
  put_le<uint64_t>(bytes, XXH3_64bits(payload.data(), payload.size()));
  bytes += payload;
  return bytes;
}

void write_checkpoint(const std::string& path, const wire::Checkpoint& c) {
  std::string payload;
  if (!c.SerializeToString(&payload)) fail("{}: cannot encode the checkpoint", path);
  write_file_atomic(path, frame_checkpoint(payload));
}

wire::Checkpoint read_checkpoint(const std::string& path) {
  return decode_checkpoint(read_file_whole(path, "checkpoint", kMaxCheckpointBytes), path);
}

wire::Checkpoint decode_checkpoint(std::string_view all, const std::string& path) {
  if (all.size() < kHeaderBytes || all.substr(0, kFileMagic.size()) != kFileMagic) fail("{}: not a sirad checkpoint", path);
  if (uint32_t v = get_le<uint32_t>(all.substr(kFileMagic.size())); v != kCheckpointVersion)
    fail("{}: checkpoint version {}; this sirad reads version {}", path, v, kCheckpointVersion);
  const std::string_view payload = all.substr(kHeaderBytes);
  if (get_le<uint64_t>(all.substr(kFileMagic.size() + 4)) != XXH3_64bits(payload.data(), payload.size()))
    fail("{}: the checkpoint is damaged (its checksum does not match its contents)", path);
  wire::Checkpoint c;
  if (!c.ParseFromArray(payload.data(), static_cast<int>(payload.size())) || c.magic() != kCheckpointMagic)
    fail("{}: not a sirad checkpoint (the contents do not decode)", path);
  if (c.version() != kCheckpointVersion)
    fail("{}: checkpoint version {}; this sirad reads version {}", path, c.version(), kCheckpointVersion);
  // Every field within what a run of this sirad can have, as the wire decoder checks a message.
  try {
    settings_of(c);  // the run's settings and its chunks (from_wire, check)
  } catch (const Error& e) {
    fail("{}: {}", path, e.what());
  }
  const wire::Run& run = c.run();
  const uint32_t chunks = static_cast<uint32_t>(run.chunk_starts_size());
  if (run.exchange_every() == kExchangeAuto) fail("{}: the run's exchange period is 'auto', not the period it ran", path);
  auto seconds_ok = [](double t) { return t >= 0 && t <= kMaxSeconds; };
  auto text_ok = [](const std::string& t) { return t.size() <= kMaxCheckpointText; };
  if (!seconds_ok(c.elapsed_s())) fail("{}: elapsed time {:.6g} s is outside 0..{:.0e} s", path, c.elapsed_s(), kMaxSeconds);
  if (!text_ok(c.ended_by()) || !text_ok(c.exchange_why())) fail("{}: a text field is over {} bytes", path, kMaxCheckpointText);
  if (c.nodes_size() > static_cast<int>(kMaxCheckpointNodes)) fail("{}: {} nodes (at most {})", path, c.nodes_size(), kMaxCheckpointNodes);
  for (const std::string& k : c.quarantined_keys())
    if (k.size() > 64) fail("{}: a quarantined key of {} bytes (a CURVE key has 40)", path, k.size());
  if (c.output_args_size() > 32 || !std::all_of(c.output_args().begin(), c.output_args().end(), text_ok))
    fail("{}: over 32 output flags, or one over {} bytes", path, kMaxCheckpointText);
  for (int n = 0; n < c.nodes_size(); ++n) {
    const wire::CheckpointNode& node = c.nodes(n);
    if (node.counts_size() != static_cast<int>(chunks) || node.sums().size() != 24 * static_cast<std::size_t>(run.patches()))
      fail("{}: node {} has {} counts and {} bytes of sums for {} chunks of {} patches", path, n, node.counts_size(),
           node.sums().size(), chunks, run.patches());
    if (node.bundles() > run.bundles() || node.error_bundles() > node.bundles())
      fail("{}: node {} counts {} bundles ({} at its error estimate) of the run's {}", path, n, node.bundles(),
           node.error_bundles(), run.bundles());
    for (uint64_t count : node.counts())
      if (count > node.bundles()) fail("{}: node {} has a chunk of {} bundles, more than its {}", path, n, count, node.bundles());
    if (!(std::isfinite(node.error()) && node.error() <= 1e6)) fail("{}: node {} has error estimate {:.6g}", path, n, node.error());
    if (!seconds_ok(node.busy_s()) || !seconds_ok(node.idle_s()))
      fail("{}: node {} has busy {:.6g} s, idle {:.6g} s (each in 0..{:.0e} s)", path, n, node.busy_s(), node.idle_s(), kMaxSeconds);
    if (!text_ok(node.name()) || !text_ok(node.why()) || node.key().size() > 64)
      fail("{}: node {} has a name, reason or key over its size", path, n);
    for (const wire::Range& r : node.done())
      if (r.last() <= r.first() || r.last() > run.bundles())
        fail("{}: node {} ran bundles [{}, {}) outside 0..{}", path, n, r.first(), r.last(), run.bundles());
  }
  try {
    snapshot_of(c);  // the ledger's ranges disjoint, the sums finite and within their counts
  } catch (const Error& e) {
    fail("{}: {}", path, e.what());
  }
  return c;
}

wire::Checkpoint make_checkpoint(const RunSettings& s, const wire::Run& run, const PolicySnapshot& snapshot,
                                 const CoordinatorRecord& record) {
  wire::Checkpoint c;
  c.set_magic(kCheckpointMagic);
  c.set_version(kCheckpointVersion);
  put_settings(c, s, run);
  put_snapshot(c, snapshot);
  for (std::size_t i = 0; i < record.nodes.size() && i < static_cast<std::size_t>(c.nodes_size()); ++i) {
    wire::CheckpointNode* n = c.mutable_nodes(static_cast<int>(i));
    n->set_name(record.nodes[i].name);
    n->set_busy_s(record.nodes[i].busy_s);
    n->set_idle_s(record.nodes[i].idle_s);
    n->set_key(record.nodes[i].key);
  }
  c.set_elapsed_s(record.elapsed_s);
  c.set_crossings(record.crossings);
  c.set_bytes_in(record.bytes_in);
  c.set_bytes_out(record.bytes_out);
  c.set_final_bytes(record.final_bytes);
  for (const std::string& k : record.quarantined_keys) c.add_quarantined_keys(k);
  return c;
}

CoordinatorRecord resume_from(const wire::Checkpoint& c, wire::Run& run, Policy& policy) {
  if (c.run().scene_hash() != run.scene_hash())
    fail("the checkpoint is of scene {}, this scene meshes to {}", c.run().scene_hash(), run.scene_hash());
  if (!std::equal(c.run().chunk_starts().begin(), c.run().chunk_starts().end(), run.chunk_starts().begin(),
                  run.chunk_starts().end()))
    fail("the checkpoint's chunks differ from this run's");
  policy.restore(snapshot_of(c));
  run.set_exchange_every(policy.exchange_every());
  run.set_exchange_fraction(policy.fraction());
  CoordinatorRecord r;
  for (const wire::CheckpointNode& n : c.nodes()) r.nodes.push_back({n.name(), n.key(), n.busy_s(), n.idle_s()});
  r.elapsed_s = c.elapsed_s();
  r.crossings = c.crossings();
  r.bytes_in = c.bytes_in();
  r.bytes_out = c.bytes_out();
  r.final_bytes = c.final_bytes();
  r.quarantined_keys.insert(c.quarantined_keys().begin(), c.quarantined_keys().end());
  return r;
}

void put_snapshot(wire::Checkpoint& c, const PolicySnapshot& s) {
  c.mutable_run()->set_exchange_every(s.exchange_every);
  c.mutable_run()->set_exchange_fraction(s.fraction);
  c.set_exchange_why(s.exchange_why);
  c.set_exchanges(s.exchanges);
  c.set_reports(s.reports);
  c.set_closing(s.closing);
  c.set_ended_by(s.ended_by);
  c.clear_nodes();
  for (const NodeRecord& r : s.nodes) {
    wire::CheckpointNode* n = c.add_nodes();
    n->set_bundles(r.state.bundles);
    n->set_exchanges(r.state.exchanges);
    n->set_error(r.state.error);
    n->set_error_bundles(r.state.error_bundles);
    n->set_quarantined(r.state.quarantined);
    n->set_why(r.state.why);
    std::string sums;
    for (const Aggregate::Part& p : r.parts) {
      n->add_counts(p.count);
      sums += proto::pack(p.sum);
    }
    n->set_sums(std::move(sums));
    for (const Range& d : r.done) {
      wire::Range* w = n->add_done();
      w->set_first(d.first);
      w->set_last(d.last);
    }
  }
}

PolicySnapshot snapshot_of(const wire::Checkpoint& c) {
  PolicySnapshot s;
  const wire::Run& run = c.run();
  s.exchange_every = run.exchange_every();
  s.fraction = run.exchange_fraction();
  s.exchange_why = c.exchange_why();
  s.exchanges = c.exchanges();
  s.reports = c.reports();
  s.closing = c.closing();
  s.ended_by = c.ended_by();
  const std::vector<uint32_t> starts(run.chunk_starts().begin(), run.chunk_starts().end());
  std::map<uint32_t, std::vector<Range>> done;
  for (int i = 0; i < c.nodes_size(); ++i) {
    const wire::CheckpointNode& n = c.nodes(i);
    NodeRecord r;
    r.state.bundles = n.bundles();
    r.state.exchanges = n.exchanges();
    r.state.error = n.error();
    r.state.error_bundles = n.error_bundles();
    r.state.quarantined = n.quarantined();
    r.state.why = n.why();
    const std::vector<double> all = proto::unpack(n.sums());
    for (std::size_t k = 0; k < starts.size(); ++k) {
      const uint32_t first = starts[k], last = k + 1 < starts.size() ? starts[k + 1] : run.patches();
      Aggregate::Part p;
      p.sum.assign(all.begin() + 3 * static_cast<std::ptrdiff_t>(first), all.begin() + 3 * static_cast<std::ptrdiff_t>(last));
      p.count = n.counts(static_cast<int>(k));
      r.parts.push_back(std::move(p));
    }
    for (const wire::Range& d : n.done()) r.done.push_back({d.first(), d.last()});
    done[static_cast<uint32_t>(i)] = r.done;
    s.nodes.push_back(std::move(r));
  }
  Ledger::from_record(run.bundles(), done);  // throws for overlapping ranges
  // The sums: as Aggregate::set checks them (finite, within count x FLT_MAX).
  std::vector<uint32_t> bounds = starts;
  bounds.push_back(run.patches());
  Aggregate check(bounds, static_cast<uint32_t>(s.nodes.size()));
  for (uint32_t n = 0; n < s.nodes.size(); ++n)
    for (uint32_t k = 0; k < s.nodes[n].parts.size(); ++k) check.check(n, k, s.nodes[n].parts[k].sum, s.nodes[n].parts[k].count);
  return s;
}

}  // namespace sirad::cluster
