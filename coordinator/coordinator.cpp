// sirad: the coordinator's message loop over a ROUTER socket.
#include "coordinator/coordinator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <map>
#include <numeric>
#include <random>

#include <fmt/format.h>

#include "core/bundle.h"
#include "core/error.h"
#include "core/scene_io.h"
#include "proto/transport.h"

namespace sirad::cluster {

namespace {

using proto::Command;
using proto::Message;

using Clock = std::chrono::steady_clock;

struct Peer {
  std::string id;       // ZeroMQ routing id
  uint32_t index = 0;   // in the run's aggregate (a node that rejoins gets a new one)
  std::string name, device;
  bool ready = false, stopped = false, final_in = false, dead = false;
  std::deque<uint64_t> grants;  // outstanding grant ids, oldest first
  uint32_t rotation = 0;        // grants given with report chunks (the rotation of S)
  uint32_t exchange = 0;
  uint64_t bundles = 0;
  double busy_s = 0, idle_s = 0;
  double error = -1;            // its last reported error estimate (<= 0: none)
  uint64_t error_bundles = 0;   // the bundles it had done then
  Clock::time_point last_seen = Clock::now(), last_sent = Clock::now(), ready_at{};
  emulation::LinkModel down;  // the emulated coordinator -> node link
  proto::DelayQueue queue;    // messages on that link
};

class Coordinator {
 public:
  Coordinator(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh)
      : router_(router), config_(config), mesh_(mesh), ledger_(config.bundles),
        starts_(chunk_starts(static_cast<uint32_t>(mesh.size()), std::min<uint32_t>(config.chunks, static_cast<uint32_t>(mesh.size())))),
        aggregate_(starts_, 0), scene_bytes_(encode_scene(config.scene)), weight_(mesh.size()) {
    // A reconnecting node keeps its routing id; the new connection takes it over.
    router_.set(zmq::sockopt::router_handover, 1);
    std::random_device rd;
    run_.set_run_id((static_cast<uint64_t>(rd()) << 32 | rd()) | 1);  // a stale message names another run
    run_.set_scene_hash(mesh.hash);
    run_.set_seed(config.seed);
    run_.set_grid(static_cast<uint32_t>(config.grid == 0 ? auto_grid(mesh) : config.grid));
    run_.set_rule(to_string(config.rule));
    run_.set_burn_in(config.burn_in);
    run_.set_directions(to_string(config.directions));
    run_.set_no_control_variate(!config.control_variate);
    if (config.directions == Directions::stratified && config.rule != UpdateRule::chain)
      fail("stratified directions need the chain rule (under average they bias the estimate: core/bundle.cpp)");
    grant_unit_ = sampling_plan(mesh, config.directions).interleave;
    // With X = 1/k shots per bundle (k an integer) the steps [k s, k (s + 1)) share shot s
    // (core/solver.h shots_of_step): grants in whole multiples of k keep each shot on one node,
    // so the nodes' chains stay independent, as the combined error estimate assumes.
    if (config.shots_per_bundle > 0.0 && config.shots_per_bundle < 1.0) {
      const double k = 1.0 / config.shots_per_bundle;
      const uint64_t whole = static_cast<uint64_t>(std::llround(k));
      if (whole > 1 && whole <= 4096 && std::fabs(k - static_cast<double>(whole)) <= 1e-9 * k)
        grant_unit_ = std::lcm(grant_unit_, whole);
    }
    check_first_shot(config.shots_per_bundle, config.shot_resolution);
    run_.set_shots_per_bundle(config.shots_per_bundle);
    run_.set_shot_resolution(static_cast<uint32_t>(config.shot_resolution));
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c) run_.add_chunk_starts(starts_[c]);
    run_.set_patches(static_cast<uint32_t>(mesh.size()));
    run_.set_exchange_every(config.exchange_every);
    run_.set_exchange_fraction(config.fraction);
    run_.set_topology(config.topology == Topology::star ? "star" : "ring");
    run_.set_mode(config.mode == Mode::sync ? "sync" : "async");
    run_.set_bundles(config.bundles);
    run_.set_target_patches(config.mesh_options.target_patches);
    run_.set_max_edge(config.mesh_options.max_edge);
    // The error estimate weighs non-emitting patches by area (emitters are mostly E, known
    // exactly); a scene where every patch emits (the furnace) weighs them all.
    double lit = 0;
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      glm::vec3 e = mesh.emission(j);
      weight_[j] = e.x + e.y + e.z > 0 ? 0.0 : static_cast<double>(mesh.area[j]);
      lit += weight_[j];
    }
    if (lit == 0)
      for (std::size_t j = 0; j < mesh.size(); ++j) weight_[j] = mesh.area[j];
  }

  RunResult run() {
    start_ = Clock::now();
    auto last_status = start_;
    while (!done()) {
      auto now = Clock::now();
      if (config_.status && seconds(now - last_status) >= config_.status_every_s) {
        last_status = now;
        config_.status(snapshot());
      }
      if (config_.timeout_s > 0 && seconds(now - start_) > config_.timeout_s)
        fail("run did not finish within {} s ({} of {} bundles done)", config_.timeout_s, ledger_.done_count(),
             config_.bundles);
      if (config_.abort && config_.abort->load()) fail("run aborted: a local node failed");
      keep_alive(now);
      check_close(now);
      auto frames = proto::receive(router_, wait_ms(now));
      if (!frames || frames->size() < 2) continue;
      std::string id = frames->front();
      Message m;
      try {
        m = proto::decode({frames->begin() + 1, frames->end()});
      } catch (const proto::ProtocolError& e) {
        log(id, e.what());
        continue;
      }
      try {
        handle(id, m);
      } catch (const Error& e) {
        if (config_.strict) throw;
        log(id, e.what());
        error(id, e.what());
      }
    }
    // FINAL is in from every live node; let the last shaped messages (STOPs) go out.
    for (auto& [id, p] : peers_) p.queue.flush(router_, std::numeric_limits<double>::infinity());
    if (config_.status) config_.status(snapshot());
    RunResult result;
    result.radiosity.resize(mesh_.size());
    for (uint32_t c = 0; c + 1 < starts_.size(); ++c) {
      std::vector<double> est = aggregate_.estimate(c);
      for (uint32_t j = starts_[c]; j < starts_[c + 1]; ++j) {
        std::size_t i = 3 * static_cast<std::size_t>(j - starts_[c]);
        result.radiosity[j] = glm::vec3(static_cast<float>(est[i]), static_cast<float>(est[i + 1]), static_cast<float>(est[i + 2]));
      }
    }
    for (const Peer* p : all_peers()) result.nodes.push_back({p->name, p->bundles, p->exchange, p->busy_s, p->idle_s, p->dead});
    result.exchange_bytes_in = bytes_in_;
    result.exchange_bytes_out = bytes_out_;
    result.final_bytes = final_bytes_;
    result.exchanges = exchanges_;
    result.crossings = crossings_;
    result.grid = static_cast<int>(run_.grid());
    result.bundles = ledger_.done_count();
    result.ended_by = ended_by_.empty() ? "budget" : ended_by_;
    return result;
  }

 private:
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  double clock(Clock::time_point t) const { return seconds(t - start_); }

  // Every peer of the run in join order: the departed (dead, replaced by a rejoin) and the current.
  std::vector<const Peer*> all_peers() const {
    std::vector<const Peer*> out;
    for (const Peer& p : departed_) out.push_back(&p);
    for (const auto& [id, p] : peers_) out.push_back(&p);
    std::sort(out.begin(), out.end(), [](const Peer* a, const Peer* b) { return a->index < b->index; });
    return out;
  }

  Status snapshot() const {
    auto now = Clock::now();
    Status s;
    s.bundles_done = ledger_.done_count();
    s.bundles = config_.bundles;
    s.elapsed_s = seconds(now - start_);
    s.error_estimate = error_estimate();
    s.exchanges = exchanges_;
    s.bytes_in = bytes_in_;
    s.bytes_out = bytes_out_;
    s.exchange_every = config_.exchange_every;
    s.exchange_fraction = config_.fraction;
    s.mode = config_.mode == Mode::sync ? "sync" : "async";
    s.topology = config_.topology == Topology::star ? "star" : "ring";
    for (const Peer* p : all_peers()) {
      Status::Node n;
      n.name = p->name;
      n.device = p->device;
      n.state = p->dead ? "dead" : p->final_in ? "done" : !p->ready ? "joining" : !p->grants.empty() ? "working" : "waiting";
      n.bundles = p->bundles;
      n.exchanges = p->exchange;
      n.last_seen_s = seconds(now - p->last_seen);
      double up = p->ready ? seconds(now - p->ready_at) : 0.0;
      n.rate = up > 0 ? static_cast<double>(p->bundles) / up : 0.0;
      n.busy_s = p->busy_s;
      n.idle_s = p->idle_s;
      s.nodes.push_back(n);
    }
    return s;
  }

  bool done() const {
    if (!ending()) return false;
    for (const auto& [id, p] : peers_)
      if (!p.dead && p.ready && !p.final_in) return false;
    return true;
  }

  // Heartbeats to every live peer that has heard nothing for an interval; flushes the emulated
  // links; declares dead the ready peers silent for `liveness` intervals.
  void keep_alive(Clock::time_point now) {
    auto interval = std::chrono::milliseconds(config_.heartbeat_ms);
    for (auto& [id, p] : peers_) {
      if (p.dead || p.final_in) continue;
      if (p.ready && now - p.last_seen > interval * config_.liveness) {
        declare_dead(p, fmt::format("silent for {:.1f} s", seconds(now - p.last_seen)));
        continue;
      }
      if (now - p.last_sent >= interval) send(p, {Command::heartbeat, {}, {}});
      p.queue.flush(router_, clock(now));
    }
  }

  void declare_dead(Peer& p, const std::string& why) {
    uint64_t back = ledger_.outstanding(p.index);
    ledger_.abandon(p.index);
    p.dead = true;
    p.grants.clear();
    p.queue.clear();
    std::fprintf(stderr, "sirad-coordinator: %s: declared dead (%s); %llu granted bundles return to the budget\n",
                 p.name.c_str(), why.c_str(), static_cast<unsigned long long>(back));
    schedule();  // a sync barrier may have been waiting on it
  }

  // Milliseconds to wait for a message: up to 100, less when an emulated link has one due.
  int wait_ms(Clock::time_point now) {
    double next = std::numeric_limits<double>::infinity();
    for (auto& [id, p] : peers_) next = std::min(next, p.queue.flush(router_, clock(now)));
    double ms = (next - clock(now)) * 1e3;
    return static_cast<int>(std::clamp(ms, 0.0, 100.0));
  }

  void log(const std::string& id, const std::string& what) {
    auto it = peers_.find(id);
    std::fprintf(stderr, "sirad-coordinator: %s: %s\n", it != peers_.end() ? it->second.name.c_str() : "unknown peer",
                 what.c_str());
  }

  // To a peer, through its emulated link when the profile shapes it.
  void send(Peer& p, const Message& m) {
    std::vector<std::string> frames = proto::encode(m);
    frames.insert(frames.begin(), p.id);
    auto now = Clock::now();
    p.last_sent = now;
    if (!p.down.shaped()) return proto::send_frames(router_, frames);
    std::size_t bytes = 0;
    for (const auto& f : frames) bytes += f.size();
    p.queue.push(p.down.deliver(clock(now), bytes), std::move(frames));
    p.queue.flush(router_, clock(now));
  }
  void error(const std::string& id, const std::string& reason) {
    wire::Error e;
    e.set_reason(reason);
    auto it = peers_.find(id);
    if (it != peers_.end() && !it->second.dead) return send(it->second, {Command::error, e, {}});
    proto::send(router_, {Command::error, e, {}}, &id);
  }

  void handle(const std::string& id, const Message& m) {
    if (m.command == Command::hello) return hello(id, std::get<wire::Hello>(m.header));
    auto it = peers_.find(id);
    if (it == peers_.end()) fail("{} before HELLO", proto::command_name(m.command));
    Peer& p = it->second;
    if (p.dead) fail("{} from a node declared dead; say HELLO to rejoin", proto::command_name(m.command));
    p.last_seen = Clock::now();
    switch (m.command) {
      case Command::ready: ready(p, std::get<wire::Ready>(m.header)); break;
      case Command::report: report(p, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::final_state: final_state(p, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::error:
        if (config_.strict) fail("{}: {}", p.name, std::get<wire::Error>(m.header).reason());
        log(id, "node: " + std::get<wire::Error>(m.header).reason());
        break;
      case Command::heartbeat: break;
      default: fail("unexpected {}", proto::command_name(m.command));
    }
  }

  // A new node, or one that lost its run (it restarted, or the emulation disconnected it): it
  // joins with a fresh index; a former entry's last state stays in the estimate.
  void hello(const std::string& id, const wire::Hello& h) {
    if (auto it = peers_.find(id); it != peers_.end()) {
      Peer& old = it->second;
      old.last_seen = Clock::now();
      // An idle node repeats HELLO until it has a run, and a node between FINAL and the next
      // run does too: nothing to do for either.
      if (!old.dead && (!old.ready || old.stopped)) return;
      if (!old.dead) declare_dead(old, "it said HELLO again: it lost its run");
      departed_.push_back(std::move(old));
      peers_.erase(it);
    }
    Peer& p = peers_[id];
    p.id = id;
    p.index = aggregate_.nodes();
    p.name = h.node_name().empty() ? fmt::format("node {}", p.index) : h.node_name();
    if (h.has_device()) p.device = h.device().name();
    aggregate_.add_node();
    wire::Welcome w;
    w.set_node_index(p.index);
    w.set_heartbeat_ms(config_.heartbeat_ms);
    w.set_liveness(config_.liveness);
    *w.mutable_run() = run_;
    if (config_.profile) {
      emulation::LinkSpec spec = config_.profile->for_node(p.index, p.name);
      if (!config_.emulate_bandwidth) spec.up_mbit = spec.down_mbit = 0;
      uint64_t seed = config_.seed * 0x9E3779B97F4A7C15ull + p.index;
      p.down = emulation::LinkModel(spec.down_mbit, spec.latency_ms, spec.jitter_ms, spec.loss, seed);
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
    for (std::size_t off = 0; off < scene_bytes_.size() || off == 0; off += proto::kMaxSceneFrameBytes) {
      wire::SceneChunk c;
      c.set_scene_hash(mesh_.hash);
      c.set_total_bytes(scene_bytes_.size());
      c.set_offset(off);
      c.set_last(off + proto::kMaxSceneFrameBytes >= scene_bytes_.size());
      send(p, {Command::scene, c, {scene_bytes_.substr(off, proto::kMaxSceneFrameBytes)}});
      if (c.last()) break;
    }
  }

  void ready(Peer& p, const wire::Ready& r) {
    if (p.ready) fail("READY twice");
    if (r.run_id() != run_.run_id()) fail("READY for run {:x}, not this run", r.run_id());
    p.ready = true;
    p.ready_at = Clock::now();
    schedule();
  }

  // Grants. Async: every live ready node holds two, the one it runs and one queued behind it,
  // so it never waits for the REPORT -> GRANT round trip; near the end of the budget (less
  // than two grants per node left) only one, so no node queues work a faster one could take.
  // Sync: one each, given only when no node holds one (the barrier of the exchange period).
  void schedule() {
    uint32_t ready = 0;
    bool any_holding = false;
    for (const auto& [id, p] : peers_) {
      if (p.dead) continue;
      ready += p.ready && !p.stopped;
      any_holding = any_holding || (p.ready && !p.grants.empty());
    }
    if (!started_ && ready < config_.min_nodes) return;  // min_nodes gates the first grant only
    started_ = true;
    if (config_.mode == Mode::sync && any_holding) return;
    std::size_t depth = config_.mode == Mode::async && ledger_.available() >= 2 * ready * grant_size() ? 2 : 1;
    for (auto& [id, p] : peers_)
      while (!closing_ && !p.dead && p.ready && !p.stopped && p.grants.size() < depth && give_grant(p)) {
      }
    if (ending())  // not before: a dead node's grant may still come back to the budget
      for (auto& [id, p] : peers_)
        if (!p.dead && p.ready && !p.stopped && p.grants.empty()) {
          wire::Stop s;
          s.set_run_id(run_.run_id());
          send(p, {Command::stop, s, {}});
          p.stopped = true;
        }
  }

  // Every bundle done, or the run closed early and every outstanding grant is in.
  bool ending() const {
    if (ledger_.finished()) return true;
    if (!closing_) return false;
    for (const auto& [id, p] : peers_)
      if (!p.dead && !p.grants.empty()) return false;
    return true;
  }

  // A time limit or the target error closes the run: no more grants, the outstanding ones finish.
  void check_close(Clock::time_point now) {
    if (closing_ || ledger_.finished()) return;
    if (config_.time_limit_s > 0 && seconds(now - start_) >= config_.time_limit_s) ended_by_ = "time limit";
    else if (config_.target_error > 0 && reports_ > last_error_check_) {
      last_error_check_ = reports_;
      double e = error_estimate();
      if (e >= 0 && e <= config_.target_error) ended_by_ = fmt::format("target error ({:.4g} <= {:.4g})", e, config_.target_error);
    }
    if (ended_by_.empty()) return;
    closing_ = true;
    std::fprintf(stderr, "sirad-coordinator: %s reached after %llu bundles: finishing the outstanding grants\n",
                 ended_by_.c_str(), static_cast<unsigned long long>(ledger_.done_count()));
    schedule();
  }

  uint64_t grant_size() const {
    uint64_t n = config_.exchange_every > 0 ? config_.exchange_every
                                            : std::max<uint64_t>(1, config_.bundles / (8 * std::max<uint32_t>(1, aggregate_.nodes())));
    // Whole multiples of the grant unit, so ranges start at multiples of it (the ledger hands
    // out its free ranges from the front): of the interleave G under stratified directions (a
    // node's chain runs same-sequence bundles >= G steps apart even across grants,
    // core/bundle.cpp) and of 1 / X when that is a whole number of steps sharing a shot.
    return (n + grant_unit_ - 1) / grant_unit_ * grant_unit_;
  }

  bool give_grant(Peer& p) {
    auto ranges = ledger_.grant(p.index, grant_size());
    if (ranges.empty()) return false;
    wire::Grant g;
    g.set_run_id(run_.run_id());
    g.set_grant_id(++grants_);
    for (const Range& r : ranges) {
      auto* w = g.add_ranges();
      w->set_first(r.first);
      w->set_last(r.last);
    }
    if (config_.exchange_every > 0)
      for (uint32_t c : exchange_chunks(p.rotation++, config_.fraction, aggregate_.chunks())) g.add_report_chunks(c);
    p.grants.push_back(g.grant_id());
    send(p, {Command::grant, g, {}});
    return true;
  }

  void take_chunks(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk, uint64_t& bytes) {
    if (r.run_id() != run_.run_id()) fail("{} for run {:x}, not this run", "state", r.run_id());
    for (int i = 0; i < r.chunks_size(); ++i) {
      if (r.chunks(i) >= aggregate_.chunks()) fail("report names chunk {} of {}", r.chunks(i), aggregate_.chunks());
      aggregate_.set(p.index, r.chunks(i), proto::unpack(bulk[i]), r.counts(i));
      bytes += bulk[i].size();
    }
    if (std::isfinite(r.busy_s()) && std::isfinite(r.idle_s())) {
      p.busy_s = std::max(p.busy_s, r.busy_s());
      p.idle_s = std::max(p.idle_s, r.idle_s());
    }
  }

  // The run's error estimate. Under the chain rule the nodes are independent chains and the
  // result is their count-weighted mean: its relative error combines each node's own
  // batch-means estimate e_p, weighted by the counts the aggregate holds for it
  // (Aggregate::combined_error; every node holding data must have an estimate); otherwise
  // (the average rule couples the nodes, or a node has too few bundles yet) the spread of the
  // node states (Aggregate::spread_error).
  double error_estimate() const {
    if (config_.rule == UpdateRule::chain) {
      std::vector<double> error(aggregate_.nodes(), -1.0);
      std::vector<uint64_t> bundles(aggregate_.nodes(), 0);
      for (const Peer* p : all_peers()) {
        if (p->index >= error.size()) continue;
        error[p->index] = p->error;
        bundles[p->index] = p->error_bundles;
      }
      double e = aggregate_.combined_error(error, bundles, weight_);
      if (e > 0) return e;
    }
    return aggregate_.spread_error(weight_);
  }

  void report(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    if (p.grants.empty() || r.grant_id() != p.grants.front()) fail("report for grant {} it does not hold", r.grant_id());
    p.grants.pop_front();  // answered, whatever follows: a refused report must not wedge the run
    try {
      for (const auto& d : r.done()) {
        ledger_.done(p.index, {d.first(), d.last()});
        p.bundles += d.last() - d.first();
      }
      // Refused like a bad chunk: the indices count as done (the ledger moves on), the data not.
      if (!std::isfinite(r.error_estimate()) || r.error_estimate() > 1e6)
        fail("REPORT error estimate {} is not a finite relative error", r.error_estimate());
      take_chunks(p, r, bulk, bytes_in_);
    } catch (const Error&) {
      schedule();  // refused (the caller logs it and answers ERROR); the others go on
      throw;
    }
    crossings_ += r.crossings();
    if (r.error_estimate() > 0) {
      p.error = r.error_estimate();
      p.error_bundles = p.bundles;  // the node's chain had run this many when it estimated
    }
    ++reports_;
    if (config_.progress) config_.progress(ledger_.done_count(), config_.bundles);
    if (r.chunks_size() > 0) {
      // The exchange: the others' aggregate (star) or the next node's state (ring).
      wire::Update u;
      u.set_run_id(run_.run_id());
      u.set_exchange(p.exchange);
      std::vector<std::string> frames;
      for (uint32_t c : r.chunks()) {
        Aggregate::Part part = aggregate_.others(p.index, c, config_.topology);
        u.add_chunks(c);
        u.add_counts(part.count);
        frames.push_back(proto::pack(part.sum));
        bytes_out_ += frames.back().size();
      }
      send(p, {Command::update, u, frames});
      ++p.exchange;
      ++exchanges_;
    }
    schedule();
  }

  void final_state(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    if (!p.stopped || p.final_in) fail("FINAL without STOP");
    take_chunks(p, r, bulk, final_bytes_);
    p.final_in = true;
  }

  zmq::socket_t& router_;
  const RunConfig& config_;
  const PatchMesh& mesh_;
  Ledger ledger_;
  std::vector<uint32_t> starts_;
  Aggregate aggregate_;
  std::string scene_bytes_;
  std::vector<double> weight_;  // per patch, for the error estimate: area if not emitting
  wire::Run run_;
  std::map<std::string, Peer> peers_;
  std::vector<Peer> departed_;
  Clock::time_point start_ = Clock::now();
  uint64_t grants_ = 0, bytes_in_ = 0, bytes_out_ = 0, final_bytes_ = 0, crossings_ = 0;
  uint32_t exchanges_ = 0;
  uint64_t reports_ = 0;
  bool started_ = false;
  bool closing_ = false;        // no more grants (time limit or target error)
  std::string ended_by_;
  uint64_t last_error_check_ = 0;
  uint64_t grant_unit_ = 1;  // grants are multiples of it (stratified G, and 1 / X)
};

}  // namespace

Attributes run_attributes(const RunConfig& c, const RunResult& r, const PatchMesh& mesh, const std::string& scene) {
  return {
      {"sirad.version", std::string(SIRAD_VERSION)},
      {"sirad.scene", scene},
      {"sirad.scene_hash", mesh.hash},
      {"sirad.patches", static_cast<int64_t>(mesh.size())},
      {"sirad.bundles", static_cast<int64_t>(r.bundles)},
      {"sirad.grid", static_cast<int64_t>(r.grid)},
      {"sirad.seed", std::to_string(c.seed)},
      {"sirad.rule", std::string(to_string(c.rule))},
      {"sirad.directions", std::string(to_string(c.directions))},
      {"sirad.control_variate", std::string(c.control_variate ? "on" : "off")},
      {"sirad.shots_per_bundle", c.shots_per_bundle},
      {"sirad.nodes", static_cast<int64_t>(r.nodes.size())},
      {"sirad.exchange_every", c.exchange_every == 0 ? std::string("end") : std::to_string(c.exchange_every)},
      {"sirad.exchange_fraction", c.fraction},
      {"sirad.topology", std::string(c.topology == Topology::star ? "star" : "ring")},
      {"sirad.mode", std::string(c.mode == Mode::sync ? "sync" : "async")},
  };
}

std::string traffic_line(const RunResult& r) {
  uint64_t e = std::max<uint64_t>(r.exchanges, 1);
  return fmt::format("exchange traffic: {} exchanges, {} B up, {} B down ({} B up, {} B down per exchange); final states {} B",
                     r.exchanges, r.exchange_bytes_in, r.exchange_bytes_out, r.exchange_bytes_in / e,
                     r.exchange_bytes_out / e, r.final_bytes);
}

std::string node_lines(const RunResult& r) {
  std::string out;
  for (const auto& n : r.nodes)
    out += fmt::format("node {}: {} bundles, {} exchanges, busy {:.2f} s, idle {:.2f} s{}\n", n.name, n.bundles,
                       n.exchanges, n.busy_s, n.idle_s, n.dead ? ", dead" : "");
  return out;
}

RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh) {
  return Coordinator(router, config, mesh).run();
}

}  // namespace sirad::cluster
