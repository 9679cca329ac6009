// sirad: the worker node's loop (proto/PROTOCOL.md sections 3.1 to 3.3).
#include "node/node.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <thread>
#include <variant>

#include <fmt/format.h>

#include "cluster/profile.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "cluster/tiles.h"
#include "cluster/worker.h"
#include "engine/bundle_cl.h"
#include "engine/version.h"
#include "node/scene_cache.h"
#include "proto/transport.h"
#include "render/gather.h"
#include "scene/camera.h"
#include "scene/encoding.h"
#include "scene/mesh.h"
#include "solver/solver.h"
#include "util/error.h"
#include "util/limits.h"
#include "util/log.h"

namespace sirad::node {

namespace {

using proto::Command;
using proto::Message;

using Clock = std::chrono::steady_clock;
constexpr auto kFreshSocketAfter = std::chrono::seconds(16);
// Silence from the coordinator this long since the node connected (or last heard it) is logged
// once: a node whose key the coordinator refuses hears nothing at all.
constexpr auto kSilenceWarning = std::chrono::seconds(10);

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// A run without emulation: real speed, no disconnect.
wire::Emulation no_emulation() {
  wire::Emulation e;
  e.set_slowdown(1);
  e.set_disconnect_at_s(-1);
  e.set_reconnect_after_s(-1);
  return e;
}

// One run on this node: the mesh, the engine and the solver, and the run's chunks.
struct RunState {
  wire::Run run;
  uint32_t index = 0;
  PatchMesh mesh;
  std::unique_ptr<BundleEngine> engine;
  std::unique_ptr<ShotEngine> shots;  // the first shot's, when the run has one
  std::unique_ptr<cluster::Worker> worker;
  uint64_t bundles = 0;  // run by this node in this run
};

// After a run whose STOP said its image follows (PROTOCOL.md section 3.4): the run's mesh,
// kept for the final gather, and once IMAGE came, the gather and its view.
struct ImageState {
  uint64_t run_id = 0;
  PatchMesh mesh;
  std::unique_ptr<FinalGather> gather;
  Camera camera;
  std::optional<cluster::TileGrid> grid;
  uint64_t tiles = 0;  // rendered here
  double busy_s = 0;
};

// Where the node is in a run, one phase at a time (PROTOCOL.md section 3): none (saying HELLO
// until a coordinator has a run for it); joining (WELCOME in: the scene arriving, or meshed
// from the cache); solving (READY sent: grants, updates, the STOP that asks for its FINAL);
// imaging (after a STOP whose image follows: IMAGE, tiles, the STOP that ends the image).
struct Joining {
  RunState run;
};
struct Solving {
  RunState run;
};
struct Imaging {
  ImageState image;
};
using Phase = std::variant<std::monostate, Joining, Solving, Imaging>;

class Node {
 public:
  Node(zmq::context_t& context, const std::string& endpoint, const NodeOptions& options)
      : context_(context), endpoint_(endpoint), options_(options), cache_(options.scene_cache) {
    device_ = describe_device(select_device(options.device));
    info(fmt::format("connecting to {}{}; device {} ({}, {} compute units)", endpoint_,
                     options_.server_key.empty() ? "" : " (CURVE)", device_.device_name, device_.platform_name,
                     device_.compute_units),
         {{"event", "start"}, {"endpoint", endpoint_}, {"device", device_.device_name}, {"platform", device_.platform_name},
          {"compute_units", device_.compute_units}, {"version", kVersion}});
    connect();
  }

  void serve() {
    auto last_hello = Clock::now();
    hello();
    while (!stopping()) {
      // Without a run, say HELLO again: a coordinator that starts (or restarts) later hears of
      // this node that way. Every reconnect_ms while a coordinator answers; while none does,
      // the wait doubles up to reconnect_max_ms.
      if (!in_run() && Clock::now() - last_hello > hello_every_) {
        // libzmq ends a connection for good on a protocol error (a frame over ZMQ_MAXMSGSIZE
        // from a broken or hostile coordinator) and never reconnects it; after 16 s of silence,
        // a fresh socket (and routing id) connects again.
        if (Clock::now() - last_heard_ > kFreshSocketAfter && Clock::now() - fresh_at_ > kFreshSocketAfter) {
          connect();
          fresh_at_ = Clock::now();
        }
        hello();
        last_hello = Clock::now();
        if (Clock::now() - last_heard_ > hello_every_)
          hello_every_ = std::min<Clock::duration>(2 * hello_every_, std::chrono::milliseconds(options_.reconnect_max_ms));
      }
      if (!tick()) {
        if (!reconnect()) return;
        last_hello = Clock::now();
        continue;
      }
      auto waiting = Clock::now();
      // A message is copied only within its command's bound for this node's run (none before
      // WELCOME: headers alone, a SCENE frame).
      const RunState* run = this->run();
      const std::size_t patches = run ? run->run.patches() : imaging() ? imaging()->mesh.size() : 0;
      auto in = proto::receive(*socket_, poll_ms(), 0, patches, run ? run->run.chunk_starts_size() : 0);
      if (solving() && granted_) idle_s_ += seconds(Clock::now() - waiting);  // blocked with nothing to run
      if (!in) {
        coordinator_liveness();
        silence_warning();
        continue;
      }
      if (warned_silence_) info("the coordinator answers", {{"event", "heard"}});
      warned_silence_ = false;
      heard_once_ = true;
      last_heard_ = Clock::now();
      hello_every_ = std::chrono::milliseconds(options_.reconnect_ms);
      Message m;
      try {
        if (in->over)
          throw proto::ProtocolError(fmt::format("a message of {} frames, {} bytes: over the bound of its command",
                                                 in->frames_seen, in->bytes_seen));
        m = proto::decode(in->frames);
      } catch (const proto::ProtocolError& e) {
        warn(fmt::format("refused a message: {}", e.what()), {{"event", "refused"}});
        continue;
      }
      if (m.command == Command::bye) {
        info("the coordinator said BYE; leaving", {{"event", "left"}, {"why", "bye"}});
        return;
      }
      handle(m);
    }
  }

 private:
  bool stopping() const { return options_.stop && options_.stop->load(); }

  // The current phase's state, or null in another phase.
  RunState* joining() {
    auto* j = std::get_if<Joining>(&phase_);
    return j ? &j->run : nullptr;
  }
  RunState* solving() {
    auto* s = std::get_if<Solving>(&phase_);
    return s ? &s->run : nullptr;
  }
  const RunState* solving() const {
    auto* s = std::get_if<Solving>(&phase_);
    return s ? &s->run : nullptr;
  }
  ImageState* imaging() {
    auto* i = std::get_if<Imaging>(&phase_);
    return i ? &i->image : nullptr;
  }
  // The run being joined or solved, or null.
  const RunState* run() const {
    if (auto* j = std::get_if<Joining>(&phase_)) return &j->run;
    return solving();
  }

  // The operator's log (util/log.h): "sirad-node NAME: ...", or a JSON line with the fields.
  void log(logging::Level level, const std::string& message, nlohmann::json fields) const {
    fields["node"] = options_.name;
    if (const RunState* r = run()) fields["run"] = fmt::format("{:016x}", r->run.run_id());
    logging::write(level, "sirad-node " + options_.name, message, fields);
  }
  void info(const std::string& message, nlohmann::json fields) const { log(logging::Level::info, message, std::move(fields)); }
  void warn(const std::string& message, nlohmann::json fields) const { log(logging::Level::warn, message, std::move(fields)); }
  void debug(const std::string& message, nlohmann::json fields) const {
    if (logging::enabled(logging::Level::debug)) log(logging::Level::debug, message, std::move(fields));
  }

  // No answer at all for a while: said once, with what is most likely wrong.
  void silence_warning() {
    if (warned_silence_ || Clock::now() - last_heard_ < kSilenceWarning) return;
    warned_silence_ = true;
    const double s = seconds(Clock::now() - last_heard_);
    warn(heard_once_ ? fmt::format("no answer from the coordinator at {} for {:.0f} s (it answered before): stopped, or "
                                   "unreachable now? saying HELLO until it answers",
                                   endpoint_, s)
         : options_.server_key.empty()
             ? fmt::format("no answer from the coordinator at {} in {:.0f} s: is it running, and reachable from here?", endpoint_, s)
             : fmt::format("no answer from the coordinator at {} in {:.0f} s: is this node's key in its allow list, and "
                           "--server-key its public key?",
                           endpoint_, s),
         {{"event", "silence"}, {"endpoint", endpoint_}, {"seconds", s}});
  }

  void connect() {
    std::random_device rd;
    socket_ = std::make_unique<zmq::socket_t>(context_, zmq::socket_type::dealer);
    socket_->set(zmq::sockopt::routing_id, fmt::format("node-{:08x}{:08x}", rd(), rd()));
    socket_->set(zmq::sockopt::linger, 0);
    socket_->set(zmq::sockopt::reconnect_ivl, options_.reconnect_ms);
    socket_->set(zmq::sockopt::reconnect_ivl_max, options_.reconnect_max_ms);
    proto::harden(*socket_, proto::max_frame_bytes(options_.max_patches, true));
    if (!options_.server_key.empty()) proto::make_curve_client(*socket_, options_.curve_keys, options_.server_key);
    socket_->connect(endpoint_);
  }

  void hello() {
    wire::Hello h;
    h.set_node_name(options_.name);
    h.set_sirad_version(kVersion);
    wire::Device* d = h.mutable_device();
    d->set_platform(device_.platform_name);
    d->set_name(device_.device_name);
    d->set_is_cpu(device_.is_cpu);
    d->set_compute_units(device_.compute_units);
    d->set_opencl_version(device_.version);
    h.set_max_message_bytes(static_cast<uint64_t>(proto::max_frame_bytes(options_.max_patches, true)));
    said_held_.clear();
    for (const std::string& hash : cache_.hashes()) {
      h.add_scene_hashes(hash);
      said_held_.insert(hash);
    }
    send({Command::hello, h, {}});
  }

  // Through the uplink (shaped when the run's profile says so). A message that cannot go (the
  // coordinator has been unreachable for HWM messages) is dropped: the coordinator declares
  // this node dead and it rejoins.
  void send(const Message& m) {
    last_sent_ = Clock::now();
    up_.send(*socket_, proto::encode(m), seconds(last_sent_ - epoch_));
  }

  int poll_ms() {
    double next = up_.flush(*socket_, seconds(Clock::now() - epoch_));
    double ms = (next - seconds(Clock::now() - epoch_)) * 1e3;
    return static_cast<int>(std::clamp(ms, 0.0, static_cast<double>(options_.poll_ms)));
  }

  // Between messages and between bundles: the emulated link's due messages go out, a HEARTBEAT
  // if nothing was sent for an interval, and the emulated disconnect. False: disconnected.
  bool tick() {
    auto now = Clock::now();
    up_.flush(*socket_, seconds(now - epoch_));
    if (!in_run()) return true;
    if (now - last_sent_ >= heartbeat_) send({Command::heartbeat, {}, {}});
    return !(solving() && emulation_.disconnect_at_s() >= 0 && seconds(now - ready_at_) >= emulation_.disconnect_at_s());
  }

  // The emulated disconnect: the socket goes (with whatever it had queued), and so does the
  // run. The node comes back as a new peer after reconnect_after_s, or leaves for good.
  bool reconnect() {
    double after = emulation_.reconnect_after_s();
    warn(fmt::format("disconnected by the emulation profile{}", after >= 0 ? fmt::format("; back in {} s", after) : " for good"),
         {{"event", "left"}, {"why", "emulated disconnect"}});
    if (const RunState* r = run()) disconnected_runs_.insert(r->run.run_id());
    socket_.reset();
    phase_ = std::monostate{};
    emulation_ = no_emulation();
    up_ = {};
    if (after < 0) return false;
    auto back = Clock::now() + std::chrono::duration<double>(after);
    while (Clock::now() < back)
      if (stopping()) return false;
      else std::this_thread::sleep_for(std::chrono::milliseconds(10));
    connect();
    hello();
    return true;
  }

  // A run whose coordinator fell silent for `liveness` intervals is over for this node: it
  // forgets the run and says HELLO until a coordinator answers.
  void coordinator_liveness() {
    if (!in_run() || Clock::now() - last_heard_ <= heartbeat_ * liveness_) return;
    warn(fmt::format("coordinator silent for {:.1f} s; leaving the run", seconds(Clock::now() - last_heard_)),
         {{"event", "left"}, {"why", "coordinator silent"}});
    leave_run();
  }

  // In a run: joining it, running it, or after it rendering its image.
  bool in_run() const { return !std::holds_alternative<std::monostate>(phase_); }

  void leave_run() {
    phase_ = std::monostate{};
    emulation_ = no_emulation();
    up_ = {};
  }

  void handle(const Message& m) {
    switch (m.command) {
      case Command::welcome: welcome(std::get<wire::Welcome>(m.header)); break;
      case Command::scene: scene(std::get<wire::SceneChunk>(m.header), m.bulk[0]); break;
      case Command::grant: grant(std::get<wire::Grant>(m.header)); break;
      case Command::update: update(std::get<wire::Update>(m.header), m.bulk); break;
      case Command::stop: stop(std::get<wire::Stop>(m.header)); break;
      case Command::image: image(std::get<wire::Image>(m.header), m.bulk[0]); break;
      case Command::tiles: tiles(std::get<wire::Grant>(m.header)); break;
      case Command::heartbeat: break;
      case Command::error: {
        const wire::Error& e = std::get<wire::Error>(m.header);
        const std::string reason = cluster::peer_text(e.reason(), kPeerTextBytes);
        // It does not know this node in its run (declared dead, or the coordinator restarted or
        // resumed from a checkpoint): leave the run and join again. The protocol's way, not a fault.
        if (e.rejoin()) {
          info(fmt::format("the coordinator asks for a HELLO ({}): joining", reason), {{"event", "rejoin"}, {"reason", reason}});
          if (in_run()) leave_run();
          hello();  // also between runs: a farm asks its idle nodes so when a job starts
        } else {
          warn(fmt::format("coordinator: {}", reason), {{"event", "error"}, {"reason", reason}});
        }
        break;
      }
      default: error(fmt::format("unexpected {}", proto::command_name(m.command)));
    }
  }

  void error(const std::string& reason) {
    wire::Error e;
    e.set_reason(reason);
    send({Command::error, e, {}});
  }

  void welcome(const wire::Welcome& w) {
    if (!w.has_run()) return;
    // Every field of the run within its bounds and this node's before anything acts on it.
    try {
      cluster::from_wire(w.run());
      if (w.run().patches() > options_.max_patches)
        fail("a run of {} patches (this node takes at most {}: sirad-node --max-patches)", w.run().patches(), options_.max_patches);
    } catch (const Error& e) {
      return error(fmt::format("WELCOME refused: {}", e.what()));
    }
    RunState& joining = phase_.emplace<Joining>().run;
    joining.run = w.run();
    joining.index = w.node_index();
    scene_bytes_.clear();
    heartbeat_ = std::chrono::milliseconds(std::clamp<uint32_t>(w.heartbeat_ms(), 10, 60000));
    liveness_ = std::clamp<uint32_t>(w.liveness(), 1, 100);
    busy_s_ = idle_s_ = 0;
    granted_ = false;
    emulation_ = w.has_emulation() ? w.emulation() : no_emulation();
    const wire::Emulation& e = emulation_;
    auto in = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
    if (!in(e.slowdown(), 1, 1e6) || !in(e.latency_ms(), 0, 6e4) || !in(e.jitter_ms(), 0, 6e4) ||
        !in(e.up_mbit(), 0, 1e6) || !in(e.loss(), 0, 0.5) || !std::isfinite(e.disconnect_at_s()) ||
        !std::isfinite(e.reconnect_after_s())) {
      error("WELCOME: emulation settings out of range; running unshaped");
      emulation_ = no_emulation();
    }
    if (disconnected_runs_.count(w.run().run_id())) emulation_.set_disconnect_at_s(-1);  // once per run
    const wire::Run& r = w.run();
    info(fmt::format("joined run {:016x} as node {}: {} patches, {} bundles, grid {}{}", r.run_id(), w.node_index(), r.patches(),
                     r.bundles(), r.grid(), emulation_.slowdown() > 1 ? fmt::format(", emulated {:.3g}x slower", emulation_.slowdown()) : ""),
         {{"event", "joined"}, {"index", w.node_index()}, {"patches", r.patches()}, {"bundles", r.bundles()}, {"grid", r.grid()},
          {"slowdown", emulation_.slowdown()}});
    up_ = proto::ShapedLink(emulation::LinkModel(emulation_.up_mbit(), emulation_.latency_ms(), emulation_.jitter_ms(),
                                                 emulation_.loss(), emulation_.seed()));
    // A scene this node said it holds is not sent: set up from the cache. Should its file have
    // been damaged or removed since the HELLO (the cache drops it), join afresh on a new socket,
    // whose HELLO no longer names it; the coordinator declares the old identity dead.
    const std::string& source = w.run().scene_source();
    if (source.empty() || !said_held_.count(source)) return;
    if (std::optional<std::string> bytes = cache_.get(source)) {
      info(fmt::format("scene {} from the cache", source), {{"event", "scene"}, {"scene", source}, {"cached", true}});
      set_up(*bytes, "scene " + source + " from the cache");
      return;
    }
    warn(fmt::format("scene {} is no longer in the cache; joining again", source), {{"event", "rejoin"}, {"scene", source}});
    leave_run();
    connect();
    hello();
  }

  // Scene chunks in order; the last one completes the scene: mesh it, check the hash, start.
  void scene(const wire::SceneChunk& c, const std::string& bytes) {
    if (!joining() || c.offset() != scene_bytes_.size()) return error("SCENE out of order");
    // No scene file sirad reads is larger (scene/scene.cpp); a claim beyond it is refused before
    // the node buffers it.
    if (c.total_bytes() > kMaxSceneBytes) {
      phase_ = std::monostate{};
      return error(fmt::format("SCENE of {} bytes (at most {})", c.total_bytes(), kMaxSceneBytes));
    }
    scene_bytes_ += bytes;
    if (!c.last()) return;
    std::string received = std::move(scene_bytes_);
    scene_bytes_.clear();
    if (set_up(received, "scene from coordinator")) {
      std::string why;
      cache_.put(received, &why);
      if (!why.empty())
        warn(fmt::format("scene not kept in {}: {}", options_.scene_cache, cluster::peer_text(why, kPeerTextBytes)), {{"event", "cache"}});
    }
  }

  // The run's set-up from the scene's bytes (sent, or from the cache): mesh it, check its hash,
  // build the engines, run the burn-in and say READY. False (and ERROR sent): it failed.
  // `label` names where the bytes came from in an error.
  bool set_up(const std::string& scene_bytes, const std::string& label) {
    try {
      RunState& joining = *this->joining();
      const wire::Run& run = joining.run;
      const cluster::RunSettings settings = cluster::from_wire(run);  // as the coordinator has them
      Scene scene = decode_scene(scene_bytes, label);
      MeshOptions mesh_options = settings.mesh_options;
      mesh_options.max_patches = run.patches();  // no more than the run says it has
      joining.mesh = mesh_scene(scene, mesh_options);
      if (joining.mesh.hash != run.scene_hash())
        fail("meshed scene hash {} differs from the run's {}", joining.mesh.hash, run.scene_hash());
      joining.engine = make_cl_engine(joining.mesh, {.device = options_.device, .path = options_.transfer});
      if (settings.shots_per_bundle > 0) joining.shots = make_cl_shot_engine(joining.mesh, options_.device);
      auto t0 = Clock::now();
      const std::vector<uint32_t> starts(run.chunk_starts().begin(), run.chunk_starts().end());
      // The burn-in can be long (up to 2^20 bundles): a stop ends it.
      joining.worker = std::make_unique<cluster::Worker>(joining.mesh, *joining.engine, joining.shots.get(), settings,
                                                         joining.index, starts, [this] { return stopping(); });
      double ms = seconds(Clock::now() - t0) * 1e3 / std::max(1, joining.worker->solver().burn_in());
      RunState& state = phase_.emplace<Solving>(Solving{std::move(joining)}).run;
      wire::Ready ready;
      ready.set_run_id(state.run.run_id());
      ready.set_scene_hash(state.mesh.hash);
      ready.set_ms_per_bundle(ms * emulation_.slowdown());
      send({Command::ready, ready, {}});
      last_heard_ = ready_at_ = Clock::now();  // setup blocked the loop; count from now
      info(fmt::format("ready: {} patches ({}), burn-in {} bundles, {:.2f} ms per bundle on {}", state.mesh.size(), label,
                       state.worker->solver().burn_in(), ms * emulation_.slowdown(), device_.device_name),
           {{"event", "ready"}, {"patches", state.mesh.size()}, {"burn_in", state.worker->solver().burn_in()},
            {"ms_per_bundle", ms * emulation_.slowdown()}, {"device", device_.device_name}});
      return true;
    } catch (const Error& e) {
      error(e.what());
      phase_ = std::monostate{};
      return false;
    }
  }

  // Run the granted bundles (each taking `slowdown` times its real time under emulation), then
  // report the chunks the grant names.
  void grant(const wire::Grant& g) {
    RunState* state = solving();
    if (!state || g.run_id() != state->run.run_id()) return error("GRANT for no run of mine");
    auto start = Clock::now();
    granted_ = true;
    wire::Report report;
    report.set_run_id(g.run_id());
    report.set_grant_id(g.grant_id());
    cluster::Worker& worker = *state->worker;
    const uint64_t crossings = worker.solver().crossings();
    std::vector<cluster::Range> ranges;
    uint64_t count = 0;
    for (const auto& r : g.ranges()) {
      ranges.push_back({r.first(), r.last()});
      count += r.last() > r.first() ? r.last() - r.first() : 0;
    }
    debug(fmt::format("grant {}: {} bundles from {}", g.grant_id(), count, g.ranges_size() > 0 ? g.ranges(0).first() : 0),
          {{"event", "grant"}, {"grant", g.grant_id()}, {"bundles", count}});
    // Between bundles: the heartbeat and the emulated disconnect (tick; false: disconnected, the
    // loop reconnects), the emulated slowdown, and a stop.
    auto t0 = Clock::now();
    const bool whole = worker.run(ranges, [&] {
      if (!tick()) return false;
      auto slow_until = t0 + std::chrono::duration_cast<Clock::duration>((Clock::now() - t0) * emulation_.slowdown());
      while (Clock::now() < slow_until) {
        std::this_thread::sleep_for(std::min<Clock::duration>(slow_until - Clock::now(), std::chrono::milliseconds(20)));
        if (!tick()) return false;
      }
      t0 = Clock::now();
      return !stopping();
    });
    if (!whole) return;
    state->bundles += count;
    for (const auto& r : g.ranges()) *report.add_done() = r;
    report.set_crossings(worker.solver().crossings() - crossings);
    busy_s_ += seconds(Clock::now() - start);
    report.set_busy_s(busy_s_);
    report.set_idle_s(idle_s_);
    // Only once the batch means are ready (8 batches, each long against the correlations between
    // consecutive estimates): fewer or shorter make an estimate that dips by chance.
    report.set_error_estimate(worker.reported_error());
    const std::vector<uint32_t> chunks(g.report_chunks().begin(), g.report_chunks().end());
    std::vector<std::string> bulk;
    try {
      bulk = chunk_frames(worker.states(chunks), report);
    } catch (const Error& e) {
      return error(fmt::format("GRANT: {}", e.what()));
    }
    Message m{Command::report, {}, std::move(bulk)};
    m.header = report;
    send(m);
  }

  // The node's (sum, count) of chunks into the report and its bulk frames.
  static std::vector<std::string> chunk_frames(const std::vector<cluster::ChunkState>& states, wire::Report& report) {
    std::vector<std::string> bulk;
    for (const cluster::ChunkState& s : states) {
      report.add_chunks(s.chunk);
      report.add_counts(s.count);
      bulk.push_back(proto::pack(s.sum));
    }
    return bulk;
  }

  // IMAGE: the view and the solution to gather from; every field checked before the gather
  // is made (its rays over this node's mesh: Embree, on the CPU).
  void image(const wire::Image& h, const std::string& solution) {
    ImageState* image = imaging();
    if (!image || h.run_id() != image->run_id) return error("IMAGE for no run of mine");
    try {
      ImageState& im = *image;
      constexpr uint32_t kMaxSide = 1u << 20;  // beyond any image: TileGrid refuses it by name
      const int width = static_cast<int>(std::min(h.width(), kMaxSide)), height = static_cast<int>(std::min(h.height(), kMaxSide));
      im.grid.emplace(width, height, static_cast<int>(std::min(h.tile(), kMaxSide)));
      im.camera = parse_camera(h.camera());
      camera_frame(im.camera, width, height, "IMAGE");  // a camera that defines a view
      check_camera_reach(im.camera, im.mesh.bound_center, im.mesh.bound_radius, "IMAGE");  // and that rays can start from
      const std::vector<double> values = proto::unpack(solution);
      if (values.size() != 3 * im.mesh.size()) fail("a solution of {} values for {} patches", values.size() / 3, im.mesh.size());
      std::vector<glm::vec3> radiosity(im.mesh.size());
      for (std::size_t j = 0; j < radiosity.size(); ++j) {
        radiosity[j] = glm::vec3(glm::dvec3(values[3 * j], values[3 * j + 1], values[3 * j + 2]));
        if (!std::isfinite(radiosity[j].x) || !std::isfinite(radiosity[j].y) || !std::isfinite(radiosity[j].z))
          fail("the solution is not finite at patch {}", j);
      }
      const int spp = static_cast<int>(std::min<uint32_t>(h.spp(), kMaxSide));
      im.gather = std::make_unique<FinalGather>(im.mesh, radiosity, GatherOptions{.width = width, .height = height, .spp = spp, .seed = h.seed(), .threads = options_.gather_threads});
      const int threads = im.gather->options().thread_count();
      info(fmt::format("image: {}x{}, {} spp, {} tiles, {} threads", width, height, spp, im.grid->count(), threads),
           {{"event", "image"}, {"width", width}, {"height", height}, {"spp", spp}, {"threads", threads}});
    } catch (const Error& e) {
      image->gather.reset();
      return error(fmt::format("IMAGE refused: {}", e.what()));
    }
  }

  // TILES: render the granted tiles (on every core; the heartbeat between this thread's rows),
  // then PIXELS.
  void tiles(const wire::Grant& g) {
    ImageState* image = imaging();
    if (!image || !image->gather || g.run_id() != image->run_id) return error("TILES for no image of mine");
    ImageState& im = *image;
    const auto start = Clock::now();
    wire::Pixels px;
    px.set_run_id(g.run_id());
    px.set_grant_id(g.grant_id());
    std::vector<std::string> bulk;
    uint64_t rays = 0;
    try {
      for (const auto& r : g.ranges()) {
        if (r.last() <= r.first() || r.last() - r.first() > proto::kMaxTilesPerGrant - bulk.size())
          fail("a grant of more than {} tiles, or an empty range", proto::kMaxTilesPerGrant);
        for (uint64_t t = r.first(); t < r.last(); ++t) {
          const cluster::TileRect rect = im.grid->rect(t);
          const GatherPasses tile = im.gather->render(im.camera, rect.x0, rect.y0, rect.x1, rect.y1, [this] { tick(); });
          if (stopping()) return;
          rays += tile.rays;
          bulk.push_back(cluster::pack_tile(tile));
        }
        *px.add_done() = r;
      }
    } catch (const Error& e) {
      return error(fmt::format("TILES: {}", e.what()));
    }
    im.tiles += bulk.size();
    const double busy = seconds(Clock::now() - start);
    im.busy_s += busy;
    px.set_busy_s(busy);
    px.set_rays(rays);
    Message m{Command::pixels, {}, std::move(bulk)};
    m.header = px;
    send(m);
  }

  void update(const wire::Update& u, const std::vector<std::string>& bulk) {
    RunState* state = solving();
    if (!state || u.run_id() != state->run.run_id()) return;
    for (int i = 0; i < u.chunks_size(); ++i) {
      try {
        state->worker->absorb(u.chunks(i), proto::unpack(bulk[i]), u.counts(i));
      } catch (const Error& e) {
        return error(fmt::format("UPDATE: {}", e.what()));
      }
    }
  }

  // STOP: the run's end (FINAL back; with image_follows the mesh is kept for the image), or
  // after the image, its end.
  void stop(const wire::Stop& s) {
    if (ImageState* image = imaging(); image && s.run_id() == image->run_id) {
      info(fmt::format("image done: {} tiles here, busy {:.2f} s", image->tiles, image->busy_s),
           {{"event", "image done"}, {"tiles", image->tiles}, {"busy_s", image->busy_s}});
      phase_ = std::monostate{};
      return;
    }
    RunState* state = solving();
    if (!state) return;
    wire::Report final_state;
    final_state.set_run_id(state->run.run_id());
    final_state.set_busy_s(busy_s_);
    final_state.set_idle_s(idle_s_);
    Message m{Command::final_state, {}, chunk_frames(state->worker->all_states(), final_state)};
    m.header = final_state;
    send(m);
    info(fmt::format("run done: {} bundles here, busy {:.2f} s, idle {:.2f} s; final state sent{}", state->bundles, busy_s_, idle_s_,
                     s.image_follows() ? "; the image follows" : ""),
         {{"event", "done"}, {"bundles", state->bundles}, {"busy_s", busy_s_}, {"idle_s", idle_s_}});
    if (s.image_follows()) {
      // The engines go first (they were made on the mesh), then the mesh moves to the image.
      state->worker.reset();
      state->shots.reset();
      state->engine.reset();
      Imaging next;
      next.image.run_id = state->run.run_id();
      next.image.mesh = std::move(state->mesh);
      phase_ = std::move(next);
    } else {
      phase_ = std::monostate{};
    }
    // The FINAL leaves through the emulated link; the next run brings its own.
    while (!up_.empty() && !stopping()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      up_.flush(*socket_, seconds(Clock::now() - epoch_));
    }
    emulation_ = no_emulation();
    up_ = {};
  }

  zmq::context_t& context_;
  std::string endpoint_;
  NodeOptions options_;
  DeviceInfo device_;
  std::unique_ptr<zmq::socket_t> socket_;
  Phase phase_;
  std::string scene_bytes_;
  SceneCache cache_;
  std::set<std::string> said_held_;  // the scene hashes of the last HELLO
  // Time: the heartbeat, the coordinator's liveness, this run's busy and idle time.
  Clock::time_point epoch_ = Clock::now(), last_sent_ = Clock::now(), last_heard_ = Clock::now();
  Clock::time_point ready_at_ = Clock::now(), fresh_at_ = Clock::now();
  Clock::duration heartbeat_ = std::chrono::seconds(1);
  Clock::duration hello_every_ = std::chrono::milliseconds(options_.reconnect_ms);
  uint32_t liveness_ = 3;
  double busy_s_ = 0, idle_s_ = 0;
  bool granted_ = false;  // this run has given a grant (idle: blocked waiting for a message after it)
  bool warned_silence_ = false;  // the silence since last_heard_ was logged
  bool heard_once_ = false;      // a coordinator has answered since this node started
  // The run's emulation (cluster/profile.h): slowdown, uplink, disconnect.
  wire::Emulation emulation_ = no_emulation();
  std::set<uint64_t> disconnected_runs_;
  proto::ShapedLink up_;  // to the coordinator
};

}  // namespace

void serve(zmq::context_t& context, const std::string& endpoint, const NodeOptions& options) {
  Node(context, endpoint, options).serve();
}

}  // namespace sirad::node
