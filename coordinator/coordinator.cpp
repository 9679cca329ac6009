// sirad: the coordinator's message loop over a ROUTER socket.
#include "coordinator/coordinator.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <set>

#include <fmt/format.h>

#include "cluster/checkpoint.h"
#include "cluster/deadlines.h"
#include "cluster/exchange_choice.h"
#include "cluster/image_phase.h"
#include "cluster/rate_limit.h"
#include "cluster/status.h"
#include "cluster/tiles.h"
#include "engine/bundle.h"
#include "engine/bundle_cl.h"
#include "proto/transport.h"
#include "render/gather.h"
#include "scene/encoding.h"
#include "solver/error_estimate.h"
#include "util/error.h"
#include "util/limits.h"
#include "util/log.h"

namespace sirad::cluster {

namespace {

using proto::Command;
using proto::Message;

using Clock = std::chrono::steady_clock;

// The image cannot be made (RunResult::image_error); the solution before it stays good.
class ImageFailed : public Error {
 public:
  using Error::Error;
};

// Pixels of each tile a node sends that the coordinator renders too and compares
// (Coordinator::spot_check): 2 of 1,024, so the checks cost a node's image 0.2 %.
constexpr int kSpotChecks = 2;

// Joins (HELLOs that make a new node entry) per CURVE key or address in any 10 s: enough for a
// farm of 256 nodes behind one address (a NAT, one host) to start at once.
constexpr uint32_t kJoinBurst = 256;
constexpr double kJoinWindowS = 10;

// Messages read one after another before the socket counts as read up to date even though more
// are waiting (a peer that floods would otherwise keep every silence from being judged).
constexpr uint32_t kReadUpToDateAfter = 4096;

// The rules of grants' due times (cluster/deadlines.h): the slack is the liveness window
// (heartbeat_ms x liveness), and at least the rules' default.
DeadlineRules deadline_rules(const RunConfig& c) {
  DeadlineRules r;
  r.slack_s = std::max(r.slack_s, c.heartbeat_ms * 1e-3 * c.liveness);
  return r;
}

// Refused because the coordinator does not know the sender in its run (never joined, declared
// dead, or this coordinator was restarted): the ERROR asks it to say HELLO again.
struct Rejoin : Error {
  using Error::Error;
};

// A node as the socket side sees it; what the policy decides about it is Policy::node(index).
struct Peer {
  std::string id;       // ZeroMQ routing id
  std::string key;      // its CURVE public key (the ZAP user id; "" without CURVE)
  std::string address;  // its IP address over tcp:// ("" over inproc)
  uint32_t index = 0;   // in the policy (a node that rejoins gets a new one)
  std::string name, device;
  double busy_s = 0, idle_s = 0;
  uint64_t bytes_in = 0, bytes_out = 0;  // its states in (REPORT, FINAL bulk) and updates out
  double ms_per_bundle = 0;  // as its READY said (its burn-in, slowdown included)
  uint64_t first_bundles = 0;  // bundles and busy time at its first report
  double first_busy_s = 0;
  Clock::time_point first_grant_at{};  // when its first grant went out (none yet: the epoch)
  Clock::time_point last_seen = Clock::now(), last_sent = Clock::now(), ready_at{};
  proto::ShapedLink down;     // the coordinator -> node link (shaped by the profile)
  bool unreachable = false;   // a send to it failed (gone, or its queue stayed full): dead
  std::string dead_why;       // why it was declared dead (the status's "why" of a dead node)
  bool from_checkpoint = false;  // a node of the run before this process resumed it
  bool image_joiner = false;    // joined during the image: its READY gets a STOP, its FINAL the IMAGE
  bool image_stop_sent = false; // that STOP went out
  bool asked_rejoin = false;    // after its FINAL, asked to rejoin: the run had bundles again
};

class Coordinator {
 public:
  Coordinator(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes)
      : router_(router), peer_bytes_(peer_bytes), config_(config), mesh_(mesh),
        policy_(make_policy(config, mesh, config.min_nodes, [this](const std::vector<uint32_t>& ready) { return choose(ready); })),
        scene_bytes_(encode_scene(config.scene)), grants_(deadline_rules(config)) {
    // A reconnecting node keeps its routing id; the new connection takes it over.
    router_.set(zmq::sockopt::router_handover, 1);
    proto::harden(router_, proto::max_frame_bytes(mesh.size()));
    run_ = to_wire(config, mesh, policy_.starts());
    run_.set_scene_source(scene_bytes_hash(scene_bytes_));
    std::random_device rd;
    run_.set_run_id((static_cast<uint64_t>(rd()) << 32 | rd()) | 1);  // a stale message names another run
    if (config.resume) resume(*config.resume);
  }

  RunResult run() {
    start_ = Clock::now() - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(record_.elapsed_s));
    {
      SolveStage solve(*this);
      loop(solve);
    }
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
        ImageStage image(*this, result);
        loop(image);
        image.finish();
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

 private:
  // One phase of the run as the loop drives it: its socket side. Its decisions are a socket-free
  // object's (the solve's Policy, the image's ImagePhase); a stage turns them into messages and
  // the messages it is sent into calls on them.
  class Stage {
   public:
    virtual ~Stage() = default;
    virtual bool finished() const = 0;
    // The run's time limit (--timeout) is reached during this phase: throws what ends it.
    [[noreturn]] virtual void out_of_time() = 0;
    // One turn at `now`: what the phase watches (liveness, due times, closing) and the work it
    // sends; true when it works here, so the loop only takes what is in already.
    virtual bool turn(Clock::time_point now) = 0;
    // A message read during the phase (its routing id first; `key` the sender's CURVE key).
    virtual void message(const proto::Received& in, const std::string& key) = 0;
  };
  class SolveStage;
  class ImageStage;

  // The one loop of every phase: each turn, what ends the run from outside (the time limit,
  // ends_now), the status on its period, the stage's turn, then one message, waited for up to
  // wait_ms.
  void loop(Stage& stage) {
    auto last_status = Clock::now();
    while (!stage.finished()) {
      auto now = Clock::now();
      if (past_time_limit(now)) stage.out_of_time();
      ends_now();
      if (config_.status && seconds(now - last_status) >= config_.status_every_s) {
        last_status = now;
        config_.status(snapshot());
      }
      const bool here = stage.turn(now);
      std::string key;
      if (auto in = next(now, key, here)) stage.message(*in, key);
    }
  }

  // The solve (PROTOCOL.md section 3): the bundles of the Policy's grants. Each turn writes the
  // checkpoint and the preview on their periods, judges liveness and grants' due times
  // (keep_alive) and closes the run when the policy says; each message goes to handle(), and
  // one it refuses is answered by an ERROR and logged: the run goes on.
  class SolveStage final : public Stage {
   public:
    explicit SolveStage(Coordinator& c) : c_(c) {}
    bool finished() const override { return c_.policy_.done(); }
    [[noreturn]] void out_of_time() override {
      fail("run did not finish within {} s ({} of {} bundles done)", c_.config_.timeout_s, c_.policy_.ledger().done_count(),
           c_.config_.bundles);
    }

    bool turn(Clock::time_point now) override {
      const RunConfig& config = c_.config_;
      if (!config.checkpoint.empty() && seconds(now - last_checkpoint_) >= config.checkpoint_every_s) {
        last_checkpoint_ = now;
        try {
          c_.checkpoint();
        } catch (const Error& e) {  // a full disk must not end the run; the last good file stays
          c_.say(logging::Level::warn, fmt::format("checkpoint not written: {}; the run goes on", e.what()), {{"event", "checkpoint"}});
        }
      }
      if (config.preview && seconds(now - last_preview_) >= config.preview_every_s && c_.holds_states()) {
        last_preview_ = now;
        config.preview(c_.policy_.radiosity());
      }
      c_.keep_alive(now);
      Policy& policy = c_.policy_;
      if ((config.close && config.close->load() && policy.close("interrupted")) || policy.check_close(seconds(now - c_.start_))) {
        c_.say(logging::Level::info,
               fmt::format("{} reached after {} bundles: finishing the outstanding grants", policy.ended_by(), policy.ledger().done_count()),
               {{"event", "closing"}, {"ended_by", policy.ended_by()}, {"bundles", policy.ledger().done_count()}});
        c_.schedule();
      }
      return false;
    }

    void message(const proto::Received& in, const std::string& key) override {
      const std::string& id = in.frames.front();
      std::optional<Message> m = c_.decoded(in);
      if (!m) return;
      try {
        c_.handle(id, key, in.address, *m);
      } catch (const Error& e) {
        if (c_.config_.strict) throw;
        c_.log(id, e.what());
        c_.error(id, e.what(), dynamic_cast<const Rejoin*>(&e) != nullptr);
        // A quarantine sticks to the node's key (under CURVE), not only to its routing id.
        if (auto it = c_.peers_.find(id); it != c_.peers_.end() && c_.policy_.node(it->second.index).quarantined && !key.empty())
          c_.record_.quarantined_keys.insert(key);
      }
    }

   private:
    Coordinator& c_;
    Clock::time_point last_checkpoint_ = Clock::now(), last_preview_ = Clock::now();
  };

  // The image (PROTOCOL.md section 3.4): the final gather of the solution, in tiles that the
  // ImagePhase (cluster/image_phase.h) grants to the nodes that sent their FINAL, two grants
  // each at a time; a node that falls silent, misses a deadline or sends what does not fit is
  // dropped and its tiles are granted again. Nodes join during the image as during the bundles
  // (image_joiner): HELLO, WELCOME, READY, then at once a STOP that says the image follows,
  // their FINAL (no bundles; the solution was final before the image began: not taken) and the
  // IMAGE. A resumed run none of whose nodes is here (its checkpoint was written during its
  // image) waits for --min-nodes of them to join before its first tile, as a run waits before
  // its first grant. With no node left otherwise, the coordinator renders the rest itself,
  // reading messages between its tiles: a node that joins takes tiles from the next one.
  // Throws ImageFailed when the image cannot be made (the solution stays good).
  class ImageStage final : public Stage {
   public:
    ImageStage(Coordinator& c, RunResult& result) : c_(c), result_(result), began_(Clock::now()), header_(c.image_header()) {
      const GatherOptions& o = c_.config_.final_gather;
      // A resumed run none of whose nodes is here to render: min_nodes to join before the first tile.
      const bool none_here = std::none_of(c_.peers_.begin(), c_.peers_.end(), [&](const auto& e) { return c_.may_render(e.second); });
      const bool wait = none_here && c_.config_.resume != nullptr;
      c_.image_ = std::make_unique<ImagePhase>(o.width, o.height, o.spp, deadline_rules(c_.config_), wait ? c_.config_.min_nodes : 0);
      std::vector<double> solution;
      solution.reserve(3 * c_.mesh_.size());
      for (const glm::vec3& b : result.radiosity) solution.insert(solution.end(), {b.x, b.y, b.z});
      bulk_ = {proto::pack(solution)};
      for (auto& [id, p] : c_.peers_)
        if (c_.may_render(p)) c_.start_image(p, header_, bulk_);
      const ImagePhase& phase = *c_.image_;
      c_.say(logging::Level::info, fmt::format("image: {}x{}, {} spp, {} tiles of {} px for {} nodes", o.width, o.height, o.spp,
                                               phase.tiles(), ImagePhase::kTileSide, phase.rendering_nodes()),
             {{"event", "image"}, {"tiles", phase.tiles()}, {"nodes", phase.rendering_nodes()}});
      c_.image_solution_ = &result.radiosity;
      c_.spot_rng_.seed(std::random_device{}());
      c_.spot_floor_ = c_.spot_floor();
      if (wait)
        c_.say(logging::Level::info,
               fmt::format("image: waiting for {} node{} to join", c_.config_.min_nodes, c_.config_.min_nodes == 1 ? "" : "s"),
               {{"event", "image waits"}, {"nodes", c_.config_.min_nodes}});
    }

    bool finished() const override { return c_.image_->finished(); }
    [[noreturn]] void out_of_time() override {
      throw ImageFailed(fmt::format("the run's time limit of {} s was reached with {} of {} tiles done", c_.config_.timeout_s,
                                    c_.image_->tiles_done(), c_.image_->tiles()));
    }

    bool turn(Clock::time_point now) override {
      ImagePhase& phase = *c_.image_;
      c_.image_keep_alive(now);
      for (ImagePhase::Order& g : phase.next_work(c_.clock(now))) c_.grant_tiles(c_.peer(g.node), g.grant);
      if (!phase.render_here()) return false;
      if (!rendering_here_) {
        rendering_here_ = true;
        c_.say(logging::Level::warn, fmt::format("image: no node left; the coordinator renders the {} tiles left", phase.tiles() - phase.tiles_done()),
               {{"event", "image"}, {"here", true}});
      }
      if (std::optional<uint64_t> t = phase.take_here()) {
        const TileRect r = phase.grid().rect(*t);
        try {
          phase.place_here(*t, c_.here().render(*c_.mesh_.camera, r.x0, r.y0, r.x1, r.y1));
        } catch (const Error& e) {
          throw ImageFailed(fmt::format("tile {} rendered here: {}", *t, e.what()));
        }
        ++result_.tiles_here;
      } else if (!waiting_for_lost_) {
        waiting_for_lost_ = true;
        c_.say(logging::Level::warn, "image: the tiles left were lost with nodes, so they wait for a node (never rendered here)",
               {{"event", "image waits"}, {"lost", true}});
      }
      return true;
    }

    void message(const proto::Received& in, const std::string& key) override { c_.image_message(in, key, header_, bulk_); }

    // The image is done: the nodes rendering it are told so, and it goes into the result.
    void finish() {
      c_.end_image();
      result_.image = std::move(c_.image_->passes());
      result_.image_tiles = c_.image_->tiles();
      result_.image_seconds = seconds(Clock::now() - began_);
      c_.say(logging::Level::info, fmt::format("image done: {} tiles in {:.2f} s", result_.image_tiles, result_.image_seconds),
             {{"event", "image done"}, {"tiles", result_.image_tiles}, {"seconds", result_.image_seconds}, {"here", result_.tiles_here}});
    }

   private:
    Coordinator& c_;
    RunResult& result_;
    Clock::time_point began_;
    wire::Image header_;            // the IMAGE every node that renders gets
    std::vector<std::string> bulk_; // and its bulk: the solution
    bool rendering_here_ = false, waiting_for_lost_ = false;  // each said once
  };

  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  double clock(Clock::time_point t) const { return seconds(t - start_); }

  // Whether the run's time limit (--timeout) is reached (the loop asks the stage what that ends).
  bool past_time_limit(Clock::time_point now) const { return config_.timeout_s > 0 && seconds(now - start_) > config_.timeout_s; }

  // What else ends the run from outside, checked each turn of the loop: an interrupt (a
  // checkpoint, then the run fails), a local node's failure.
  void ends_now() {
    if (config_.interrupt && config_.interrupt->load()) {
      if (config_.checkpoint.empty()) fail("interrupted after {} bundles (no --checkpoint)", policy_.ledger().done_count());
      checkpoint();
      fail("interrupted after {} bundles; checkpoint in {}: continue with --resume {}", policy_.ledger().done_count(),
           config_.checkpoint, config_.checkpoint);
    }
    if (config_.abort && config_.abort->load()) fail("run aborted: a local node failed");
  }

  // The next message (its routing id first), within the bound of its command; nothing after
  // wait_ms. Keeps read_up_to_ (keep_alive's judge) and, behind a broker, puts the sender's
  // CURVE key in `key` and its address in the message.
  // `no_wait`: only what is in already (the coordinator renders tiles between reads).
  std::optional<proto::Received> next(Clock::time_point now, std::string& key, bool no_wait = false) {
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

  // A message as decode reads it, or nothing (logged) when it was over its command's bound or
  // malformed.
  std::optional<Message> decoded(const proto::Received& in) {
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

  bool imaging() const { return config_.final_gather.spp > 0 && mesh_.camera.has_value(); }
  // Whether `p` renders tiles of the run's image now.
  bool rendering(const Peer& p) const { return image_ && image_->rendering(p.index); }

  // Whether `p` renders the image when it begins: its FINAL is in, and it is live.
  bool may_render(const Peer& p) const {
    const NodeState& n = policy_.node(p.index);
    return !n.dead && !n.quarantined && n.final_in;
  }

  // `p` renders tiles from now: the IMAGE, with the solution as its bulk.
  void start_image(Peer& p, const wire::Image& h, const std::vector<std::string>& bulk) {
    grants_.clear(p.index);
    image_->join(p.index);
    send(p, {Command::image, h, bulk});
  }

  // The IMAGE message every node that renders tiles gets (with the solution as its bulk).
  wire::Image image_header() const {
    const GatherOptions& o = config_.final_gather;
    wire::Image h;
    h.set_run_id(run_.run_id());
    h.set_camera(camera_spec(*mesh_.camera));
    h.set_width(static_cast<uint32_t>(o.width));
    h.set_height(static_cast<uint32_t>(o.height));
    h.set_spp(static_cast<uint32_t>(o.spp));
    h.set_seed(o.seed);
    h.set_tile(static_cast<uint32_t>(ImagePhase::kTileSide));
    return h;
  }

  // The spot checks' absolute floor: 1e-6 of the scene's largest radiance (an emission, the
  // background).
  double spot_floor() const {
    double top = std::max({mesh_.background.x, mesh_.background.y, mesh_.background.z});
    for (const Material& m : mesh_.materials) top = std::max(top, static_cast<double>(std::max({m.emission.x, m.emission.y, m.emission.z})));
    return top * 1e-6;
  }

  // A message during the image: a HELLO joins (join_image), a node joining the image goes on
  // with it (joiner), a node rendering tiles sends PIXELS; what else comes is ignored, and what a
  // rendering node sends that does not fit drops it from the image.
  void image_message(const proto::Received& in, const std::string& key, const wire::Image& h, const std::vector<std::string>& bulk) {
    const std::string id = in.frames.front();
    std::optional<Message> m = decoded(in);
    if (!m) return;
    if (m->command == Command::hello) return join_image(id, key, in.address, *m);
    auto it = peers_.find(id);
    if (it != peers_.end() && it->second.image_joiner && !rendering(it->second) && it->second.key == key &&
        !policy_.node(it->second.index).dead)
      return joiner(it->second, *m, h, bulk);
    // Nodes dropped from the image, or done with it, have nothing to say to it.
    if (it == peers_.end() || !rendering(it->second) || it->second.key != key) {
      if (m->command != Command::heartbeat)
        log(id, fmt::format("{} during the image, from no node rendering it: ignored", proto::command_name(m->command)));
      return;
    }
    Peer& p = it->second;
    p.last_seen = Clock::now();
    try {
      switch (m->command) {
        case Command::pixels: pixels(p, std::get<wire::Pixels>(m->header), m->bulk); break;
        case Command::heartbeat: break;
        case Command::error: fail("node: {}", peer_text(std::get<wire::Error>(m->header).reason(), kPeerTextBytes));
        default: fail("unexpected {} during the image", proto::command_name(m->command));
      }
    } catch (const Error& e) {
      drop_from_image(p, e.what());
    }
  }

  // A HELLO during the image: a new node (or one that lost its run) joins as during the bundles
  // (hello: WELCOME and the scene), marked to join the image; a node already known (one
  // repeating HELLO while idle) changes nothing.
  void join_image(const std::string& id, const std::string& key, const std::string& address, const Message& m) {
    auto before = peers_.find(id);
    const std::optional<uint32_t> index = before == peers_.end() ? std::nullopt : std::optional<uint32_t>(before->second.index);
    try {
      handle(id, key, address, m);
    } catch (const Error& e) {
      if (config_.strict) throw;
      log(id, e.what());
      error(id, e.what());
      return;
    }
    auto after = peers_.find(id);
    if (after != peers_.end() && (!index || after->second.index != *index)) after->second.image_joiner = true;
  }

  // A message from a node that joined during the image and has no IMAGE yet: READY gets the
  // STOP that says the image follows, the FINAL that answers it the IMAGE (its states are not
  // taken: the solution was final before the image began). Anything else, or a run id not this
  // run's, drops it (declared dead: it may say HELLO again).
  void joiner(Peer& p, const Message& m, const wire::Image& h, const std::vector<std::string>& bulk) {
    p.last_seen = Clock::now();
    try {
      switch (m.command) {
        case Command::ready: {
          const auto& r = std::get<wire::Ready>(m.header);
          if (r.run_id() != run_.run_id()) fail("READY for run {:x}, not this run", r.run_id());
          if (p.image_stop_sent) fail("READY twice");
          p.ready_at = Clock::now();
          p.ms_per_bundle = r.ms_per_bundle();
          wire::Stop s;
          s.set_run_id(run_.run_id());
          s.set_image_follows(true);
          send(p, {Command::stop, s, {}});
          p.image_stop_sent = true;
          return;
        }
        case Command::final_state: {
          if (!p.image_stop_sent) fail("FINAL without STOP");
          if (std::get<wire::Report>(m.header).run_id() != run_.run_id()) fail("FINAL for another run");
          start_image(p, h, bulk);
          say(logging::Level::info, fmt::format("{} joined the image", p.name), {{"event", "image joined"}, {"peer", p.name}});
          return;
        }
        case Command::heartbeat: return;
        case Command::error:
          log(p.id, "node: " + peer_text(std::get<wire::Error>(m.header).reason(), kPeerTextBytes));
          return;
        default: fail("unexpected {} while joining the image", proto::command_name(m.command));
      }
    } catch (const Error& e) {
      if (config_.strict) throw;
      drop_joiner(p, e.what());
    }
  }

  void drop_joiner(Peer& p, const std::string& why) {
    policy_.dead(p.index);  // it holds no bundles: it joined during the image
    p.dead_why = why;
    p.down.clear();
    grants_.clear(p.index);
    log(p.id, fmt::format("dropped while joining the image ({})", why));
    error(p.id, why, true);
  }

  // A TILES grant to `p` (its due time is the ImagePhase's).
  void grant_tiles(Peer& p, const TileGrant& g) {
    wire::Grant w;
    w.set_run_id(run_.run_id());
    w.set_grant_id(g.id);
    for (const Range& r : g.tiles) {
      auto* wr = w.add_ranges();
      wr->set_first(r.first);
      wr->set_last(r.last);
    }
    send(p, {Command::tiles, w, {}});
  }

  void pixels(Peer& p, const wire::Pixels& px, const std::vector<std::string>& bulk) {
    if (px.run_id() != run_.run_id()) fail("PIXELS for run {:x}, not this run", px.run_id());
    std::vector<Range> done;
    for (const auto& r : px.done()) done.push_back({r.first(), r.last()});
    const std::optional<double> tile_s =
        image_->take_result(p.index, px.grant_id(), done, bulk, px.busy_s(), kMaxSeconds, clock(Clock::now()),
                            [&](const TileRect& r, const std::vector<float>& v) { spot_check(r, v); });
    for (const std::string& f : bulk) p.bytes_in += f.size();
    if (tile_s)
      say(logging::Level::info, fmt::format("image: first tiles now due within {:.1f} s of now ({} times {}'s {:.3f} s a tile)",
                                            grants_.rules().slack_s + grants_.rules().unequal_first * *tile_s,
                                            grants_.rules().unequal_first, p.name, *tile_s),
          {{"event", "first tiles due"}, {"tile_s", *tile_s}});
  }

  // Once `measured` has reported its first grant (it took t s from going out, compilation
  // included), the first grants of the nodes that have reported none are due by t
  // (Deadlines::tighten): a node that heartbeats but never reports, or runs sixteen times
  // slower, is declared dead then and its bundles granted again, not after the allowance.
  void tighten_first_grants(const Peer& measured) {
    const auto now = Clock::now();
    const double t = seconds(now - measured.first_grant_at);
    if (measured.first_grant_at == Clock::time_point{} || !(t < first_grant_s_)) return;
    first_grant_s_ = t;
    std::vector<uint32_t> unmeasured;
    for (const auto& [id, q] : peers_)
      if (!rendering(q) && policy_.node(q.index).bundles == 0 && !policy_.node(q.index).dead) unmeasured.push_back(q.index);
    if (grants_.tighten(unmeasured, clock(now), t))
      say(logging::Level::info, fmt::format("first grants now due within {:.1f} s of now ({} times {}'s first grant, {:.3f} s)",
                                            grants_.rules().slack_s + grants_.rules().unequal_first * t,
                                            grants_.rules().unequal_first, measured.name, t),
          {{"event", "first grants due"}, {"first_grant_s", t}});
  }

  // What a node's first grant may take beyond its bound (PoCL compiling its kernels at their first
  // use): the rules' first_grant_s, or, once a node has reported its first grant, unequal_first
  // times the quickest such grant took, compilation included, if that is less.
  double first_grant_allowance() const {
    return std::min(grants_.rules().first_grant_s, grants_.rules().unequal_first * first_grant_s_);
  }

  // The final gather on this machine, made at its first use (a spot check, or tiles no node is
  // left to render): the rays of the whole mesh, as a node's.
  const FinalGather& here() {
    if (!here_) here_ = std::make_unique<FinalGather>(mesh_, *image_solution_, config_.final_gather);
    return *here_;
  }

  // kSpotChecks pixels of each tile a node sends, chosen here as it arrives (no node can know
  // which), rendered here and compared (cluster/tiles.h check_pixel): a node whose pixels are
  // finite but not the image's is caught where it changed the pixels checked (every tile it
  // changed throughout).
  void spot_check(const TileRect& r, const std::vector<float>& values) {
    for (int k = 0; k < kSpotChecks; ++k) {
      const int x = r.x0 + static_cast<int>(spot_rng_() % static_cast<uint64_t>(r.x1 - r.x0));
      const int y = r.y0 + static_cast<int>(spot_rng_() % static_cast<uint64_t>(r.y1 - r.y0));
      const std::size_t i = (static_cast<std::size_t>(y - r.y0) * static_cast<std::size_t>(r.x1 - r.x0) + static_cast<std::size_t>(x - r.x0)) * 9;
      check_pixel(&values[i], here().render(*mesh_.camera, x, y, x + 1, y + 1), spot_floor_, x, y);
    }
  }

  // The image phase's liveness: as keep_alive's, for the nodes rendering tiles and those joining
  // the image (watched from their READY, as in a run).
  void image_keep_alive(Clock::time_point now) {
    for (auto& [id, p] : peers_) {
      if (rendering(p)) {
        if (std::string why = gone(p, true, image_->overdue(p.index, clock(read_up_to_))); !why.empty()) drop_from_image(p, why);
        else keep_in_touch(p, now);
      } else if (p.image_joiner && !policy_.node(p.index).dead) {
        if (std::string why = gone(p, p.image_stop_sent); !why.empty()) drop_joiner(p, why);
        else keep_in_touch(p, now);
      }
    }
  }

  // `p` renders no more of the image: its outstanding tiles go back (those it sent stay).
  void drop_from_image(Peer& p, const std::string& why) {
    image_->drop(p.index);
    log(p.id, fmt::format("dropped from the image ({}); its outstanding tiles are granted again", why));
    stop_image(p);
    if (std::optional<uint64_t> t = image_->poisoned())
      throw ImageFailed(fmt::format("tile {} was lost with {} nodes, each gone while it rendered the tile: it may crash whoever "
                                    "renders it, so it is not handed out again",
                                    *t, TilePlan::kMaxTileLosses));
  }

  // The image is over (done, or failed): every node still rendering it is told so.
  void end_image() {
    for (auto& [id, p] : peers_)
      if (rendering(p)) {
        image_->drop(p.index);
        stop_image(p);
      }
  }

  // The image's STOP (without image_follows): the node forgets the run.
  void stop_image(Peer& p) {
    wire::Stop s;
    s.set_run_id(run_.run_id());
    send(p, {Command::stop, s, {}});
  }

  // --exchange-every auto: each ready node's bundle time from its READY (its burn-in, slowdown
  // included) and its link's transfer time, the scene from a quick fit on this machine (its
  // OpenCL device, else the plain C++ reference engine) when the model needs it.
  ExchangeSetting choose(const std::vector<uint32_t>& ready) {
    std::vector<NodeCost> costs;
    for (uint32_t n : ready) {
      const Peer& p = peer(n);
      std::optional<emulation::LinkSpec> spec;
      if (config_.profile) spec = config_.profile->for_node(n, p.name);
      double t = p.ms_per_bundle > 0 && std::isfinite(p.ms_per_bundle) ? p.ms_per_bundle / 1e3 : 0.01;
      costs.push_back({t, exchange_seconds(mesh_.size(), spec ? &*spec : nullptr)});
    }
    ExchangeSetting s = auto_setting(config_, mesh_, costs, policy_.aggregate().chunks());
    say(logging::Level::info, fmt::format("--exchange-every auto: {}", s.why),
        {{"event", "exchange"}, {"exchange_every", s.exchange_every}, {"fraction", s.fraction}});
    return s;
  }

  // Whether any node's state is in (a preview of nothing is not worth drawing).
  bool holds_states() const {
    for (uint32_t c = 0; c < policy_.aggregate().chunks(); ++c)
      if (policy_.aggregate().count(c) > 0) return true;
    return false;
  }

  // Every peer of the run in join order: the departed (dead, replaced by a rejoin) and the current.
  std::vector<const Peer*> all_peers() const {
    std::vector<const Peer*> out;
    for (const Peer& p : departed_) out.push_back(&p);
    for (const auto& [id, p] : peers_) out.push_back(&p);
    std::sort(out.begin(), out.end(), [](const Peer* a, const Peer* b) { return a->index < b->index; });
    return out;
  }

  // The status now; `last`: the run's last, which says how it ended.
  Status snapshot(bool last = false) const {
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

  // Heartbeats to every live peer that has heard nothing for an interval; flushes the emulated
  // links; declares dead the ready peers silent for `liveness` intervals and those past a grant's
  // due time. Both are judged at read_up_to_, not now: after a stall of this process (a slow
  // fsync on a loaded machine) the heartbeats that came meanwhile wait in the socket, and a node
  // is silent only if the socket, read up to date, holds nothing newer from it.
  void keep_alive(Clock::time_point now) {
    for (auto& [id, p] : peers_) {
      const NodeState& n = policy_.node(p.index);
      if (n.dead) continue;
      if (n.final_in) {  // done with the run; waiting for the image, it hears from us meanwhile
        // Bundles to run again (a node quarantined at its FINAL gave them back): a node that
        // waits for the image says no HELLO by itself, so it is asked to, and rejoins.
        if (imaging() && !policy_.closing() && policy_.ledger().available() > 0 && !p.asked_rejoin) {
          p.asked_rejoin = true;
          wire::Error e;
          e.set_reason("bundles to run again; say HELLO");
          e.set_rejoin(true);
          send(p, {Command::error, e, {}});
        }
        if (imaging()) keep_in_touch(p, now);
        else p.down.flush(router_, clock(now));
        continue;
      }
      if (std::string why = gone(p, n.ready); !why.empty()) declare_dead(p, why, true);
      else keep_in_touch(p, now);
    }
  }

  // Why `p` is gone, or "": a message to it could not be sent, it has been silent for the
  // liveness window (when `watched`: a node is not before its READY), or its oldest grant is
  // past due (`overdue`: the image's word; by default its bundles'). Silence and deadlines are
  // judged at read_up_to_ (keep_alive says why).
  std::string gone(const Peer& p, bool watched, std::optional<std::string> overdue = std::nullopt) const {
    if (p.unreachable || p.down.failed() > 0) return "a message to it could not be sent";
    if (watched && read_up_to_ - p.last_seen > liveness_window())
      return fmt::format("silent for {:.1f} s", seconds(read_up_to_ - p.last_seen));
    return overdue ? *overdue : grants_.overdue(p.index, clock(read_up_to_));
  }

  // The tiles of the image `p` sent.
  uint64_t tiles_by(const Peer& p) const { return image_ ? image_->tiles_by(p.index) : 0; }

  // A HEARTBEAT to `p` if nothing went to it for an interval, and its emulated link's due messages.
  void keep_in_touch(Peer& p, Clock::time_point now) {
    if (now - p.last_sent >= std::chrono::milliseconds(config_.heartbeat_ms)) send(p, {Command::heartbeat, {}, {}});
    p.down.flush(router_, clock(now));
  }

  // How long a peer may be silent (heartbeat_ms x liveness).
  Clock::duration liveness_window() const { return std::chrono::milliseconds(config_.heartbeat_ms) * config_.liveness; }

  // `p` is dead for `why`. `gone` (silent, unreachable, past due, and not an emulated
  // disconnect): it may have crashed on its bundles, which count a loss by its CURVE key, else
  // its address (Policy::lost).
  void declare_dead(Peer& p, const std::string& why, bool gone) {
    const bool poisoned_before = policy_.ledger().poisoned(Policy::kMaxBundleLosses).has_value();
    const uint64_t back = gone && !disconnected_on_purpose(p) ? policy_.lost(p.index, p.key.empty() ? p.address : p.key)
                                                              : policy_.dead(p.index);
    p.dead_why = why;
    p.down.clear();
    grants_.clear(p.index);
    log(p.id, fmt::format("declared dead ({}); {} granted bundles return to the budget", why, back));
    if (!poisoned_before && policy_.ledger().poisoned(Policy::kMaxBundleLosses))
      say(logging::Level::error, policy_.ended_by(), {{"event", "bundles lost"}});
    schedule();  // a sync barrier may have been waiting on it
  }

  // Whether `p` went silent because its emulated link said so (the profile's disconnect_at_s,
  // past since it was ready): its grant's bundles did not crash it.
  bool disconnected_on_purpose(const Peer& p) const {
    if (!config_.profile || p.ready_at == Clock::time_point{}) return false;
    const double at = config_.profile->for_node(p.index, p.name).disconnect_at_s;
    return at >= 0 && seconds(Clock::now() - p.ready_at) >= at;
  }

  // Milliseconds to wait for a message: up to 100, less when an emulated link has one due.
  int wait_ms(Clock::time_point now) {
    double next = std::numeric_limits<double>::infinity();
    for (auto& [id, p] : peers_) next = std::min(next, p.down.flush(router_, clock(now)));
    double ms = (next - clock(now)) * 1e3;
    return static_cast<int>(std::clamp(ms, 0.0, 100.0));
  }

  // A line about a peer: at most 5 per routing id every 10 s; the next line that goes says how
  // many were held back (a flood of refusals is a few lines, not one per message).
  void log(const std::string& id, const std::string& what) {
    uint64_t held = 0;
    if (!log_limit_.allow(id, clock(Clock::now()), &held)) return;
    auto it = peers_.find(id);
    const std::string name = it != peers_.end() ? it->second.name : "unknown peer";
    say(logging::Level::warn, fmt::format("{}: {}{}", name, what, held ? fmt::format(" ({} more lines like it held back)", held) : ""),
        {{"event", "peer"}, {"peer", name}});
  }

  // A line of the operator's log (util/log.h), with the run's id among its fields.
  void say(logging::Level level, const std::string& message, nlohmann::json fields) const {
    fields["run"] = fmt::format("{:016x}", run_.run_id());
    logging::write(level, "sirad-coordinator", message, fields);
  }

  // To a peer, through its link (shaped when the profile says so).
  void send(Peer& p, const Message& m) {
    std::vector<std::string> frames = proto::encode(m);
    frames.insert(frames.begin(), p.id);
    auto now = Clock::now();
    p.last_sent = now;
    p.unreachable = p.unreachable || !p.down.send(router_, std::move(frames), clock(now));
  }
  void error(const std::string& id, const std::string& reason, bool rejoin = false) {
    wire::Error e;
    e.set_reason(reason);
    e.set_rejoin(rejoin);
    auto it = peers_.find(id);
    if (it != peers_.end() && !policy_.node(it->second.index).dead) return send(it->second, {Command::error, e, {}});
    proto::send(router_, {Command::error, e, {}}, &id);
  }

  void handle(const std::string& id, const std::string& key, const std::string& address, const Message& m) {
    if (m.command == Command::hello) {
      if (!key.empty() && record_.quarantined_keys.count(key)) fail("HELLO from the key of a quarantined node: refused");
      return hello(id, key, address, std::get<wire::Hello>(m.header));
    }
    auto it = peers_.find(id);
    if (it == peers_.end()) throw Rejoin(fmt::format("{} before HELLO", proto::command_name(m.command)));
    Peer& p = it->second;
    // Under CURVE a peer is its key: another key on its routing id (a node that took it over)
    // is refused without touching the node that has it.
    if (p.key != key) fail("{} on the routing id of {} from another key: refused", proto::command_name(m.command), p.name);
    const NodeState& n = policy_.node(p.index);
    if (n.quarantined) fail("{} from a quarantined node ({})", proto::command_name(m.command), n.why);
    if (n.dead) throw Rejoin(fmt::format("{} from a node declared dead; say HELLO to rejoin", proto::command_name(m.command)));
    p.last_seen = Clock::now();
    switch (m.command) {
      case Command::ready: ready(p, std::get<wire::Ready>(m.header)); break;
      case Command::report: report(p, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::final_state: final_state(p, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::error:
        if (config_.strict) fail("{}: {}", p.name, peer_text(std::get<wire::Error>(m.header).reason(), kPeerTextBytes));
        log(id, "node: " + peer_text(std::get<wire::Error>(m.header).reason(), kPeerTextBytes));
        break;
      case Command::heartbeat: break;
      default: fail("unexpected {}", proto::command_name(m.command));
    }
  }

  // A new node, or one that lost its run (it restarted, or the emulation disconnected it): it
  // joins with a fresh index; a former entry's last state stays in the estimate.
  void hello(const std::string& id, const std::string& key, const std::string& address, const wire::Hello& h) {
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

  void ready(Peer& p, const wire::Ready& r) {
    if (r.run_id() != run_.run_id()) fail("READY for run {:x}, not this run", r.run_id());
    policy_.ready(p.index);
    p.ready_at = Clock::now();
    p.ms_per_bundle = r.ms_per_bundle();
    say(logging::Level::info, fmt::format("{} ready: {:.2f} ms per bundle", p.name, p.ms_per_bundle),
        {{"event", "ready"}, {"peer", p.name}, {"ms_per_bundle", p.ms_per_bundle}});
    schedule();
  }

  // Sends what the policy orders: grants, then STOPs.
  void schedule() {
    Orders orders = policy_.schedule();
    for (const GrantOrder& o : orders.grants) {
      wire::Grant g;
      g.set_run_id(run_.run_id());
      g.set_grant_id(o.id);
      for (const Range& r : o.ranges) {
        auto* w = g.add_ranges();
        w->set_first(r.first);
        w->set_last(r.last);
      }
      for (uint32_t c : o.report_chunks) g.add_report_chunks(c);
      Peer& p = peer(o.node);
      uint64_t bundles = 0;
      for (const Range& r : o.ranges) bundles += r.size();
      const auto now = Clock::now();
      const double bound = policy_.grant_time_bound(p.index, bundles, p.ms_per_bundle / 1e3);
      const double first = policy_.node(p.index).bundles == 0 ? first_grant_allowance() : 0.0;
      if (p.first_grant_at == Clock::time_point{}) p.first_grant_at = now;
      grants_.add(p.index, o.id, clock(now), bound + first);
      send(p, {Command::grant, g, {}});
    }
    for (uint32_t n : orders.stops) {
      wire::Stop s;
      s.set_run_id(run_.run_id());
      s.set_image_follows(imaging());
      send(peer(n), {Command::stop, s, {}});
    }
  }

  Peer& peer(uint32_t index) {
    for (auto& [id, p] : peers_)
      if (p.index == index) return p;
    fail("no peer with index {}", index);  // the policy orders only current peers
  }

  // The REPORT or FINAL's chunks as the policy takes them (the run id checked first).
  std::vector<ChunkState> chunk_states(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk, uint64_t& bytes) {
    if (r.run_id() != run_.run_id()) fail("{} for run {:x}, not this run", "state", r.run_id());
    std::vector<ChunkState> out;
    for (int i = 0; i < r.chunks_size(); ++i) {
      out.push_back({r.chunks(i), proto::unpack(bulk[i]), r.counts(i)});
      bytes += bulk[i].size();
    }
    // Times a node reports are its own word: taken only within [0, kMaxSeconds].
    auto plausible = [](double t) { return t >= 0 && t <= kMaxSeconds; };
    if (plausible(r.busy_s()) && plausible(r.idle_s())) {
      p.busy_s = std::max(p.busy_s, r.busy_s());
      p.idle_s = std::max(p.idle_s, r.idle_s());
    }
    return out;
  }

  void report(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    std::optional<Exchange> x;
    try {
      std::vector<Range> done;
      for (const auto& d : r.done()) done.push_back({d.first(), d.last()});
      // A report for a grant it does not hold is refused before its data is looked at; one for
      // its grant whose data is refused still answers the grant, without the data.
      uint64_t bytes = 0;
      std::vector<ChunkState> chunks;
      std::string refused;
      const NodeState& n = policy_.node(p.index);
      // Another run's id on the grant it holds: no honest node sends that, and nothing of it
      // may count (its done ranges included).
      if (r.run_id() != run_.run_id() && !n.grants.empty() && r.grant_id() == n.grants.front()) {
        const std::string why = fmt::format("REPORT for grant {} names run {:x}, not this run", r.grant_id(), r.run_id());
        policy_.quarantine(p.index, why);
        grants_.clear(p.index);
        fail("{}: quarantined", why);
      }
      if (!n.grants.empty() && r.grant_id() == n.grants.front()) {
        try {
          chunks = chunk_states(p, r, bulk, bytes);
        } catch (const Error& e) {
          refused = e.what();
          chunks.clear();
        }
      }
      x = policy_.report(p.index, r.grant_id(), done, std::move(chunks), refused.empty() ? r.error_estimate() : 0.0);
      grants_.settle(p.index, r.grant_id());
      if (!refused.empty()) throw Error(refused);
      record_.bytes_in += bytes;
      p.bytes_in += bytes;
    } catch (const Error&) {
      schedule();  // refused (the caller logs it and answers ERROR); the others go on
      throw;
    }
    record_.crossings += r.crossings();
    // Its speed as it runs, for balanced grants: busy time (emulated slowdown included) over
    // bundles since its first report (the first grant carries the kernels' compilation).
    if (uint64_t b = policy_.node(p.index).bundles; b > 0) {
      if (p.first_bundles == 0) {
        p.first_bundles = b, p.first_busy_s = p.busy_s;
        tighten_first_grants(p);
      }
      else if (b > p.first_bundles) policy_.set_bundle_time(p.index, (p.busy_s - p.first_busy_s) / static_cast<double>(b - p.first_bundles));
    }
    if (config_.progress) config_.progress(policy_.ledger().done_count(), config_.bundles);
    if (x) {
      // The exchange: the others' aggregate (star) or the next node's state (ring).
      wire::Update u;
      u.set_run_id(run_.run_id());
      u.set_exchange(x->exchange);
      std::vector<std::string> frames;
      for (std::size_t i = 0; i < x->chunks.size(); ++i) {
        u.add_chunks(x->chunks[i]);
        u.add_counts(x->parts[i].count);
        frames.push_back(proto::pack(x->parts[i].sum));
        record_.bytes_out += frames.back().size();
        p.bytes_out += frames.back().size();
      }
      send(p, {Command::update, u, frames});
    }
    schedule();
  }

  void final_state(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    if (!policy_.node(p.index).stopped) fail("FINAL without STOP");
    try {
      uint64_t bytes = 0;
      policy_.final_state(p.index, chunk_states(p, r, bulk, bytes));
      record_.final_bytes += bytes;
      p.bytes_in += bytes;
    } catch (const Error&) {
      schedule();  // a quarantine gave bundles back
      throw;
    }
  }

  // Everything accepted so far, into config_.checkpoint (atomically).
  void checkpoint() {
    CoordinatorRecord r = record_;
    r.nodes.resize(policy_.nodes());
    for (const Peer* p : all_peers()) r.nodes.at(p->index) = {p->name, p->key, p->busy_s, p->idle_s};
    r.elapsed_s = seconds(Clock::now() - start_);
    wire::Checkpoint c = make_checkpoint(config_, run_, policy_.snapshot(), r);
    for (const std::string& a : config_.output_args) c.add_output_args(a);
    write_checkpoint(config_.checkpoint, c);
  }

  // A checkpointed run, continued: its nodes (departed: their processes rejoin as new nodes),
  // its ledger and counters; the scene and the chunks must be the same.
  void resume(const wire::Checkpoint& c) {
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

  zmq::socket_t& router_;
  proto::PeerBytes* peer_bytes_;  // told of each message read (may be null)
  const RunConfig& config_;
  const PatchMesh& mesh_;
  Policy policy_;
  std::string scene_bytes_;
  uint32_t scenes_sent_ = 0, scenes_from_cache_ = 0;  // joins that were sent the scene, or held it
  wire::Run run_;
  std::map<std::string, Peer> peers_;
  std::vector<Peer> departed_;
  // The run's counters and quarantined keys (what a checkpoint keeps besides the policy and the
  // peers); elapsed_s: the run's time before a resume.
  CoordinatorRecord record_;
  uint64_t resumed_bundles_ = 0, resumed_crossings_ = 0;  // done before this process resumed the run
  RateLimit log_limit_{5, 10.0};
  RateLimit join_limit_{kJoinBurst, kJoinWindowS};
  Clock::time_point start_ = Clock::now();
  // When the socket was last read up to date (a receive found nothing waiting, or
  // kReadUpToDateAfter messages were read in a row), and how many were read since.
  Clock::time_point read_up_to_ = Clock::now();
  uint32_t read_in_a_row_ = 0;
  Deadlines grants_;                   // when each node's bundle grants are due (clock())
  std::unique_ptr<ImagePhase> image_;  // the image phase's decisions, once it has begun
  double first_grant_s_ = std::numeric_limits<double>::infinity();  // the quickest first grant reported (tighten_first_grants)
  const std::vector<glm::vec3>* image_solution_ = nullptr;  // the solution the image is gathered from
  std::unique_ptr<FinalGather> here_;                       // here(): made at its first use
  std::mt19937_64 spot_rng_;                                // which pixels spot_check renders
  double spot_floor_ = 0;                                   // check_pixel's floor for spot_check
};

}  // namespace

void check_real_run(const RunConfig& config) {
  if (config.profile && config.profile->coordinator)
    fail("profile{}: 'coordinator' (the coordinator's own link) is modelled only by sirad emulate; a real coordinator's link "
         "is the machine's (shape it with tc)",
         config.profile->name.empty() ? "" : " " + config.profile->name);
}

RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes) {
  check_real_run(config);
  return Coordinator(router, config, mesh, peer_bytes).run();
}

}  // namespace sirad::cluster
