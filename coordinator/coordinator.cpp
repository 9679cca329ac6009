// sirad: the coordinator's loop over a ROUTER socket (coordinator.h), and what every phase
// shares: reading and decoding, joins (HELLO, WELCOME and the scene), sending, liveness, the
// log, the status, checkpoints.
#include "coordinator/coordinator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cluster/checkpoint.h"
#include "coordinator/session.h"
#include "scene/encoding.h"
#include "util/limits.h"

namespace sirad::cluster::detail {

Coordinator::Coordinator(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes)
    : router_(router), peer_bytes_(peer_bytes), config_(config), mesh_(mesh),
      policy_(make_policy(config, mesh, config.min_nodes, [this](const std::vector<uint32_t>& ready) { return choose(ready); })),
      scene_bytes_(encode_scene(config.scene)), grants_(grant_deadlines(config)) {
  // A reconnecting node keeps its routing id; the new connection takes it over.
  router_.set(zmq::sockopt::router_handover, 1);
  proto::harden(router_, proto::max_frame_bytes(mesh.size()));
  run_ = to_wire(config, mesh, policy_.starts());
  run_.set_scene_source(scene_bytes_hash(scene_bytes_));
  std::random_device rd;
  run_.set_run_id((static_cast<uint64_t>(rd()) << 32 | rd()) | 1);  // a stale message names another run
  if (config.resume) resume(*config.resume);
}

RunResult Coordinator::run() {
  start_ = Clock::now() - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(record_.elapsed_s));
  loop(*solve_stage());
  for (const auto& [id, held] : log_limit_.held()) {
    auto it = peers_.find(id);
    const std::string name = it != peers_.end() ? it->second.name : "unknown peer";
    say(logging::Level::warn, fmt::format("{}: {} more lines like its last held back", name, held),
        {{"event", "held back"}, {"peer", name}, {"lines", held}});
  }
  const double solved_s = seconds(Clock::now() - start_);
  RunResult result = policy_result(policy_, static_cast<int>(run_.grid()));
  if (imaging()) {
    try {
      const std::unique_ptr<Stage> image = image_stage(result);
      loop(*image);
      image->finish();
    } catch (const ImageFailed& e) {  // the solution stays good: the caller keeps it
      end_image();
      result.image.reset();
      result.image_error = e.what();
      say(logging::Level::error, fmt::format("image failed: {}", e.what()), {{"event", "image failed"}, {"error", e.what()}});
    }
  }
  // FINAL is in from every live node (and the image's tiles); let the last shaped messages
  // (STOPs) go out.
  for (auto& [id, p] : peers_) p.down.flush(router_, std::numeric_limits<double>::infinity());
  if (config_.status) config_.status(snapshot(true));
  for (const Peer* p : all_peers()) {
    const NodeState& n = policy_.node(p->index);
    result.nodes.push_back({p->name, n.bundles, n.exchanges, p->busy_s, p->idle_s, n.dead, n.why, p->from_checkpoint, tiles_by(*p)});
    for (const Range& r : policy_.ledger().done_by(p->index)) result.ledger.push_back({p->index, p->name, r});
  }
  result.exchange_bytes_in = record_.bytes_in;
  result.exchange_bytes_out = record_.bytes_out;
  result.final_bytes = record_.final_bytes;
  result.crossings = record_.crossings;
  result.bundles_before = resumed_bundles_;
  result.crossings_before = resumed_crossings_;
  result.seconds = solved_s;
  return result;
}

void Coordinator::loop(Stage& stage) {
  auto last_status = Clock::now();
  while (!stage.finished()) {
    auto now = Clock::now();
    ends_now();
    if (past_time_limit(now)) stage.out_of_time();
    if (config_.status && seconds(now - last_status) >= config_.status_every_s) {
      last_status = now;
      config_.status(snapshot());
    }
    const bool here = stage.turn(now);
    std::string key;
    if (auto in = next(now, key, here)) stage.message(*in, key);
  }
}

void Coordinator::ends_now() {
  if (config_.interrupt && config_.interrupt->load()) {
    if (config_.checkpoint.empty()) fail("interrupted after {} bundles (no --checkpoint)", policy_.ledger().done_count());
    checkpoint();
    fail("interrupted after {} bundles; checkpoint in {}: continue with --resume {}", policy_.ledger().done_count(),
         config_.checkpoint, config_.checkpoint);
  }
  if (config_.abort && config_.abort->load()) fail("run aborted: a local node failed");
}

std::optional<proto::Received> Coordinator::next(Clock::time_point now, std::string& key, bool no_wait) {
  const int ms = wait_ms(now);
  auto in = proto::receive(router_, no_wait ? 0 : ms, 1, mesh_.size(), run_.chunk_starts_size(), &key);
  if (in && peer_bytes_) peer_bytes_->delivered(in->fd, in->frames_seen, in->bytes_seen);
  if (!in || ++read_in_a_row_ >= kReadUpToDateAfter) {
    read_up_to_ = now;
    read_in_a_row_ = 0;
  }
  if (!in || in->frames.empty()) return std::nullopt;
  if (config_.peer_identity) {
    PeerIdentity who = config_.peer_identity(in->frames.front());
    key = std::move(who.key);
    in->address = std::move(who.address);
  }
  return in;
}

std::optional<Message> Coordinator::decoded(const proto::Received& in) {
  try {
    if (in.over)
      throw proto::ProtocolError(fmt::format("refused a message of {} frames, {} bytes: over the bound of its command",
                                             in.frames_seen, in.bytes_seen));
    return proto::decode({in.frames.begin() + 1, in.frames.end()});
  } catch (const proto::ProtocolError& e) {
    log(in.frames.front(), e.what());
    return std::nullopt;
  }
}

std::vector<const Peer*> Coordinator::all_peers() const {
  std::vector<const Peer*> out;
  for (const Peer& p : departed_) out.push_back(&p);
  for (const auto& [id, p] : peers_) out.push_back(&p);
  std::sort(out.begin(), out.end(), [](const Peer* a, const Peer* b) { return a->index < b->index; });
  return out;
}

Status Coordinator::snapshot(bool last) const {
  auto now = Clock::now();
  Status s = policy_status(policy_, config_, last);
  s.elapsed_s = seconds(now - start_);
  s.image_tiles = image_ ? image_->tiles() : 0;
  s.image_tiles_done = image_ ? image_->tiles_done() : 0;
  s.bytes_in = record_.bytes_in;
  s.bytes_out = record_.bytes_out;
  s.scenes_sent = scenes_sent_;
  s.scenes_from_cache = scenes_from_cache_;
  for (const Peer* p : all_peers()) {
    const NodeState& ns = policy_.node(p->index);
    Status::Node& n = s.nodes.at(p->index);
    n.name = p->name;
    n.device = p->device;
    n.last_seen_s = seconds(now - p->last_seen);
    double up = ns.ready ? seconds(now - p->ready_at) : 0.0;
    n.rate = up > 0 ? static_cast<double>(ns.bundles) / up : 0.0;
    n.busy_s = p->busy_s;
    n.idle_s = p->idle_s;
    n.bytes_in = p->bytes_in;
    n.bytes_out = p->bytes_out;
    n.tiles = tiles_by(*p);
    if (ns.dead && !ns.quarantined) n.why = p->dead_why;
    if (p->image_joiner && !ns.dead && rendering(*p)) n.state = "done";  // its FINAL is in (not taken)
    if (p->from_checkpoint) {  // not dead: it ran in the run before this process resumed it
      n.state = "before resume";
      n.rate = 0;
    }
  }
  return s;
}

std::string Coordinator::gone(const Peer& p, bool watched, std::optional<std::string> overdue) const {
  if (p.unreachable || p.down.failed() > 0) return "a message to it could not be sent";
  if (watched && read_up_to_ - p.last_seen > liveness_window())
    return fmt::format("silent for {:.1f} s", seconds(read_up_to_ - p.last_seen));
  return overdue ? *overdue : grants_.overdue(p.index, clock(read_up_to_));
}

void Coordinator::keep_in_touch(Peer& p, Clock::time_point now) {
  if (now - p.last_sent >= std::chrono::milliseconds(config_.heartbeat_ms)) send(p, {Command::heartbeat, {}, {}});
  p.down.flush(router_, clock(now));
}

int Coordinator::wait_ms(Clock::time_point now) {
  double next = std::numeric_limits<double>::infinity();
  for (auto& [id, p] : peers_) next = std::min(next, p.down.flush(router_, clock(now)));
  double ms = (next - clock(now)) * 1e3;
  return static_cast<int>(std::clamp(ms, 0.0, 100.0));
}

void Coordinator::log(const std::string& id, const std::string& what) {
  uint64_t held = 0;
  if (!log_limit_.allow(id, clock(Clock::now()), &held)) return;
  auto it = peers_.find(id);
  const std::string name = it != peers_.end() ? it->second.name : "unknown peer";
  say(logging::Level::warn, fmt::format("{}: {}{}", name, what, held ? fmt::format(" ({} more lines like it held back)", held) : ""),
      {{"event", "peer"}, {"peer", name}});
}

void Coordinator::say(logging::Level level, const std::string& message, nlohmann::json fields) const {
  fields["run"] = fmt::format("{:016x}", run_.run_id());
  logging::write(level, "sirad-coordinator", message, fields);
}

void Coordinator::send(Peer& p, const Message& m) {
  std::vector<std::string> frames = proto::encode(m);
  frames.insert(frames.begin(), p.id);
  auto now = Clock::now();
  p.last_sent = now;
  p.unreachable = p.unreachable || !p.down.send(router_, std::move(frames), clock(now));
}

void Coordinator::hello(const std::string& id, const std::string& key, const std::string& address, const wire::Hello& h) {
  if (!key.empty() && record_.quarantined_keys.count(key)) fail("HELLO from the key of a quarantined node: refused");
  if (auto it = peers_.find(id); it != peers_.end()) {
    Peer& old = it->second;
    const NodeState& n = policy_.node(old.index);
    if (old.key != key && !n.dead) fail("HELLO on the routing id of {} from another key: refused", old.name);
    old.last_seen = Clock::now();
    if (n.quarantined) fail("HELLO from a quarantined node ({}): refused", n.why);
    // An idle node repeats HELLO until it has a run, and a node between FINAL and the next
    // run does too: nothing to do for either, unless the budget has work again (a node
    // quarantined at its FINAL gave its bundles back): then it rejoins, its FINAL kept.
    bool work = n.final_in && !policy_.closing() && policy_.ledger().available() > 0;
    if (!n.dead && (!n.ready || n.stopped) && !work) return;
    if (!n.dead && !n.final_in) declare_dead(old, "it said HELLO again: it lost its run", false);
    departed_.push_back(std::move(old));
    peers_.erase(it);
  }
  // Joins are limited per CURVE key, else per address: a peer that cycles HELLO and READY
  // cannot grow the run's node entries faster than this (each costs a few hundred bytes; its
  // chunk states are allocated only when it sends one).
  if (!join_limit_.allow(key.empty() ? address : key, clock(Clock::now())))
    fail("HELLO: more than {} joins from {} in {} s: refused", kJoinBurst, key.empty() ? address : "its key", kJoinWindowS);
  const uint32_t index = policy_.join();
  // A reused index (Policy::join): the departed entry it held is forgotten.
  std::erase_if(departed_, [&](const Peer& d) { return d.index == index; });
  Peer& p = peers_[id];
  p.id = id;
  p.key = key;
  p.address = address;
  p.index = index;
  // What a peer names itself reaches logs, the summary and the status: printable ASCII only.
  p.name = h.node_name().empty() ? fmt::format("node {}", p.index) : peer_text(h.node_name(), 64);
  if (h.has_device()) p.device = peer_text(h.device().name(), 128);
  say(logging::Level::info,
      fmt::format("{} joined as node {} from {} ({})", p.name, p.index, address.empty() ? "inproc" : address,
                  p.device.empty() ? "no device named" : p.device),
      {{"event", "joined"}, {"peer", p.name}, {"index", p.index}, {"address", address}, {"device", p.device}});
  wire::Welcome w;
  w.set_node_index(p.index);
  w.set_heartbeat_ms(config_.heartbeat_ms);
  w.set_liveness(config_.liveness);
  *w.mutable_run() = run_;
  if (config_.profile) {
    emulation::LinkSpec spec = config_.profile->for_node(p.index, p.name);
    if (!config_.emulate_bandwidth) spec.up_mbit = spec.down_mbit = 0;
    uint64_t seed = emulation::link_seed(config_.seed, p.index);
    p.down = proto::ShapedLink(emulation::LinkModel(spec.down_mbit, spec.latency_ms, spec.jitter_ms, spec.loss, seed));
    wire::Emulation* e = w.mutable_emulation();
    e->set_slowdown(config_.profile->slowdown(spec));
    e->set_latency_ms(spec.latency_ms);
    e->set_jitter_ms(spec.jitter_ms);
    e->set_up_mbit(spec.up_mbit);
    e->set_loss(spec.loss);
    e->set_disconnect_at_s(spec.disconnect_at_s);
    e->set_reconnect_after_s(spec.reconnect_after_s);
    e->set_seed(seed + 1);
  }
  send(p, {Command::welcome, w, {}});
  // A node that holds the scene (by its source hash) meshes it from its cache: nothing to send.
  const auto& held = h.scene_hashes();
  if (std::find(held.begin(), held.end(), run_.scene_source()) != held.end()) {
    ++scenes_from_cache_;
    return;
  }
  ++scenes_sent_;
  for (std::size_t off = 0; off < scene_bytes_.size() || off == 0; off += proto::kMaxSceneFrameBytes) {
    wire::SceneChunk c;
    c.set_scene_hash(run_.scene_source());
    c.set_total_bytes(scene_bytes_.size());
    c.set_offset(off);
    c.set_last(off + proto::kMaxSceneFrameBytes >= scene_bytes_.size());
    send(p, {Command::scene, c, {scene_bytes_.substr(off, proto::kMaxSceneFrameBytes)}});
    if (c.last()) break;
  }
}

wire::Grant Coordinator::grant_of(uint64_t id, const std::vector<Range>& ranges) const {
  wire::Grant g;
  g.set_run_id(run_.run_id());
  g.set_grant_id(id);
  for (const Range& r : ranges) {
    auto* w = g.add_ranges();
    w->set_first(r.first);
    w->set_last(r.last);
  }
  return g;
}

void Coordinator::error(const std::string& id, const std::string& reason, bool rejoin) {
  wire::Error e;
  e.set_reason(reason);
  e.set_rejoin(rejoin);
  auto it = peers_.find(id);
  if (it != peers_.end() && !policy_.node(it->second.index).dead) return send(it->second, {Command::error, e, {}});
  proto::send(router_, {Command::error, e, {}}, &id);
}

void Coordinator::checkpoint() {
  CoordinatorRecord r = record_;
  r.nodes.resize(policy_.nodes());
  for (const Peer* p : all_peers()) r.nodes.at(p->index) = {p->name, p->key, p->busy_s, p->idle_s};
  r.elapsed_s = seconds(Clock::now() - start_);
  wire::Checkpoint c = make_checkpoint(config_, run_, policy_.snapshot(), r);
  for (const std::string& a : config_.output_args) c.add_output_args(a);
  write_checkpoint(config_.checkpoint, c);
}

void Coordinator::resume(const wire::Checkpoint& c) {
  record_ = resume_from(c, run_, policy_);
  const CoordinatorRecord& r = record_;
  resumed_bundles_ = policy_.ledger().done_count();
  resumed_crossings_ = r.crossings;
  for (std::size_t i = 0; i < r.nodes.size(); ++i) {
    Peer p;
    p.index = static_cast<uint32_t>(i);
    p.id = fmt::format("checkpointed-{}", i);
    p.name = r.nodes[i].name;
    p.key = r.nodes[i].key;
    p.busy_s = r.nodes[i].busy_s;
    p.idle_s = r.nodes[i].idle_s;
    p.from_checkpoint = true;
    departed_.push_back(std::move(p));
  }
  say(logging::Level::info,
      fmt::format("resumed after {:.1f} s: {} of {} bundles done by {} nodes; the rest to run", record_.elapsed_s,
                  policy_.ledger().done_count(), config_.bundles, c.nodes_size()),
      {{"event", "resumed"}, {"bundles_done", policy_.ledger().done_count()}, {"nodes_before", c.nodes_size()}});
}

}  // namespace sirad::cluster::detail

namespace sirad::cluster {

void check_real_run(const RunConfig& config) {
  if (config.profile && config.profile->coordinator)
    fail("profile{}: 'coordinator' (the coordinator's own link) is modelled only by sirad emulate; a real coordinator's link "
         "is the machine's (shape it with tc)",
         config.profile->name.empty() ? "" : " " + config.profile->name);
}

RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes) {
  check_real_run(config);
  return detail::Coordinator(router, config, mesh, peer_bytes).run();
}

}  // namespace sirad::cluster
