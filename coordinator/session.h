// sirad: the coordinator's inside, shared by its three files and by nothing else: the Peer as the
// socket side sees it, and the Coordinator, whose one loop (coordinator.cpp) drives a run's
// phases as stages: the solve (solve_stage.cpp: grants, reports, joins and liveness of the
// bundles) and the image (image_stage.cpp: tiles, spot checks, nodes joining the image). The
// decisions are the socket-free objects' (cluster/policy.h, cluster/image_phase.h).
#pragma once
#include <chrono>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <zmq.hpp>

#include "cluster/checkpoint.h"
#include "cluster/deadlines.h"
#include "cluster/exchange_choice.h"
#include "cluster/image_phase.h"
#include "cluster/policy.h"
#include "cluster/rate_limit.h"
#include "cluster/result.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "proto/codec.h"
#include "proto/peer_bytes.h"
#include "proto/transport.h"
#include "render/gather.h"
#include "scene/mesh.h"
#include "util/error.h"
#include "util/log.h"

namespace sirad::cluster::detail {

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
inline constexpr int kSpotChecks = 2;

// Joins (HELLOs that make a new node entry) per CURVE key or address in any 10 s: enough for a
// farm of 256 nodes behind one address (a NAT, one host) to start at once.
inline constexpr uint32_t kJoinBurst = 256;
inline constexpr double kJoinWindowS = 10;

// Messages read one after another before the socket counts as read up to date even though more
// are waiting (a peer that floods would otherwise keep every silence from being judged).
inline constexpr uint32_t kReadUpToDateAfter = 4096;

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
  Coordinator(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh, proto::PeerBytes* peer_bytes);

  RunResult run();

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
    // The phase is finished: what it made goes into the result.
    virtual void finish() {}
  };

  // ---- what every phase shares (coordinator.cpp) ----

  // The one loop of every phase: each turn, what ends the run from outside (ends_now, then the
  // time limit: an interrupt's checkpoint comes first), the status on its period, the stage's
  // turn, then one message, waited for up to wait_ms.
  void loop(Stage& stage);

  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  double clock(Clock::time_point t) const { return seconds(t - start_); }

  // Whether the run's time limit (--timeout) is reached (the loop asks the stage what that ends).
  bool past_time_limit(Clock::time_point now) const { return config_.timeout_s > 0 && seconds(now - start_) > config_.timeout_s; }

  // What else ends the run from outside, checked each turn of the loop: an interrupt (a
  // checkpoint, then the run fails), a local node's failure.
  void ends_now();

  // The next message (its routing id first), within the bound of its command; nothing after
  // wait_ms. Keeps read_up_to_ (keep_alive's judge) and, behind a broker, puts the sender's
  // CURVE key in `key` and its address in the message.
  // `no_wait`: only what is in already (the coordinator renders tiles between reads).
  std::optional<proto::Received> next(Clock::time_point now, std::string& key, bool no_wait = false);

  // A message as decode reads it, or nothing (logged) when it was over its command's bound or
  // malformed.
  std::optional<Message> decoded(const proto::Received& in);

  // Every peer of the run in join order: the departed (dead, replaced by a rejoin) and the current.
  std::vector<const Peer*> all_peers() const;

  // The status now; `last`: the run's last, which says how it ended.
  Status snapshot(bool last = false) const;

  // Why `p` is gone, or "": a message to it could not be sent, it has been silent for the
  // liveness window (when `watched`: a node is not before its READY), or its oldest grant is
  // past due (`overdue`: the image's word; by default its bundles'). Silence and deadlines are
  // judged at read_up_to_ (keep_alive says why).
  std::string gone(const Peer& p, bool watched, std::optional<std::string> overdue = std::nullopt) const;

  // The tiles of the image `p` sent.
  uint64_t tiles_by(const Peer& p) const { return image_ ? image_->tiles_by(p.index) : 0; }

  // A HEARTBEAT to `p` if nothing went to it for an interval, and its emulated link's due messages.
  void keep_in_touch(Peer& p, Clock::time_point now);

  // How long a peer may be silent (heartbeat_ms x liveness).
  Clock::duration liveness_window() const { return std::chrono::milliseconds(config_.heartbeat_ms) * config_.liveness; }

  // Milliseconds to wait for a message: up to 100, less when an emulated link has one due.
  int wait_ms(Clock::time_point now);

  // A line about a peer: at most 5 per routing id every 10 s; the next line that goes says how
  // many were held back (a flood of refusals is a few lines, not one per message).
  void log(const std::string& id, const std::string& what);

  // A line of the operator's log (util/log.h), with the run's id among its fields.
  void say(logging::Level level, const std::string& message, nlohmann::json fields) const;

  // A new node, or one that lost its run (it restarted, or the emulation disconnected it): it
  // joins with a fresh index; a former entry's last state stays in the estimate. Every phase
  // takes joins through it; a quarantined key is refused.
  void hello(const std::string& id, const std::string& key, const std::string& address, const wire::Hello& h);

  // To a peer, through its link (shaped when the profile says so).
  void send(Peer& p, const Message& m);
  // A GRANT (bundles) or TILES (tiles) message of grant `id` for `ranges`.
  wire::Grant grant_of(uint64_t id, const std::vector<Range>& ranges) const;
  void error(const std::string& id, const std::string& reason, bool rejoin = false);

  // Everything accepted so far, into config_.checkpoint (atomically).
  void checkpoint();

  // A checkpointed run, continued: its nodes (departed: their processes rejoin as new nodes),
  // its ledger and counters; the scene and the chunks must be the same.
  void resume(const wire::Checkpoint& c);

  // ---- the solve (solve_stage.cpp) ----

  // The solve stage (solve_stage.cpp): the bundles of the Policy's grants.
  class SolveStage;
  std::unique_ptr<Stage> solve_stage();

  // Once `measured` has reported its first grant (it took t s from going out, compilation
  // included), the first grants of the nodes that have reported none are due by t
  // (Deadlines::tighten): a node that heartbeats but never reports, or runs sixteen times
  // slower, is declared dead then and its bundles granted again, not after the allowance.
  void tighten_first_grants(const Peer& measured);

  // What a node's first grant may take beyond its bound (PoCL compiling its kernels at their first
  // use): the rules' first_grant_s, or, once a node has reported its first grant, unequal_first
  // times the quickest such grant took, compilation included, if that is less.
  double first_grant_allowance() const;

  // --exchange-every auto: each ready node's bundle time from its READY (its burn-in, slowdown
  // included) and its link's transfer time, the scene from a quick fit on this machine (its
  // OpenCL device, else the plain C++ reference engine) when the model needs it.
  ExchangeSetting choose(const std::vector<uint32_t>& ready);

  // Whether any node's state is in (a preview of nothing is not worth drawing).
  bool holds_states() const;

  // Heartbeats to every live peer that has heard nothing for an interval; flushes the emulated
  // links; declares dead the ready peers silent for `liveness` intervals and those past a grant's
  // due time. Both are judged at read_up_to_, not now: after a stall of this process (a slow
  // fsync on a loaded machine) the heartbeats that came meanwhile wait in the socket, and a node
  // is silent only if the socket, read up to date, holds nothing newer from it.
  void keep_alive(Clock::time_point now);

  // `p` is dead for `why`. `gone` (silent, unreachable, past due, and not an emulated
  // disconnect): it may have crashed on its bundles, which count a loss by its CURVE key, else
  // its address (Policy::lost).
  void declare_dead(Peer& p, const std::string& why, bool gone);

  // Whether `p` went silent because its emulated link said so (the profile's disconnect_at_s,
  // past since it was ready): its grant's bundles did not crash it.
  bool disconnected_on_purpose(const Peer& p) const;

  void handle(const std::string& id, const std::string& key, const std::string& address, const Message& m);

  void ready(Peer& p, const wire::Ready& r);

  // Sends what the policy orders: grants, then STOPs.
  void schedule();

  Peer& peer(uint32_t index);

  // The REPORT or FINAL's chunks as the policy takes them (the run id checked first).
  std::vector<ChunkState> chunk_states(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk, uint64_t& bytes);

  void report(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk);

  void final_state(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk);

  // ---- the image (image_stage.cpp) ----

  // The image stage (image_stage.cpp): the final gather in tiles; throws ImageFailed when the
  // image cannot be made (the solution stays good).
  class ImageStage;
  std::unique_ptr<Stage> image_stage(RunResult& result);

  bool imaging() const { return config_.final_gather.spp > 0 && mesh_.camera.has_value(); }
  // Whether `p` renders tiles of the run's image now.
  bool rendering(const Peer& p) const { return image_ && image_->rendering(p.index); }

  // Whether `p` renders the image when it begins: its FINAL is in, and it is live.
  bool may_render(const Peer& p) const;

  // `p` renders tiles from now: the IMAGE, with the solution as its bulk.
  void start_image(Peer& p, const wire::Image& h, const std::vector<std::string>& bulk);

  // The IMAGE message every node that renders tiles gets (with the solution as its bulk).
  wire::Image image_header() const;

  // The spot checks' absolute floor: 1e-6 of the scene's largest radiance (an emission, the
  // background).
  double spot_floor() const;

  // A message during the image: a HELLO joins (join_image), a node joining the image goes on
  // with it (joiner), a node rendering tiles sends PIXELS; what else comes is ignored, and what a
  // rendering node sends that does not fit drops it from the image.
  void image_message(const proto::Received& in, const std::string& key, const wire::Image& h, const std::vector<std::string>& bulk);

  // A HELLO during the image: a new node (or one that lost its run) joins as during the bundles
  // (hello: WELCOME and the scene), marked to join the image; a node already known (one
  // repeating HELLO while idle) changes nothing.
  void join_image(const std::string& id, const std::string& key, const std::string& address, const Message& m);

  // A message from a node that joined during the image and has no IMAGE yet: READY gets the
  // STOP that says the image follows, the FINAL that answers it the IMAGE (its states are not
  // taken: the solution was final before the image began). Anything else, or a run id not this
  // run's, drops it (declared dead: it may say HELLO again).
  void joiner(Peer& p, const Message& m, const wire::Image& h, const std::vector<std::string>& bulk);

  void drop_joiner(Peer& p, const std::string& why);

  // A TILES grant to `p` (its due time is the ImagePhase's).
  void grant_tiles(Peer& p, const TileGrant& g);

  void pixels(Peer& p, const wire::Pixels& px, const std::vector<std::string>& bulk);

  // The final gather on this machine, made at its first use (a spot check, or tiles no node is
  // left to render): the rays of the whole mesh, as a node's.
  const FinalGather& here();

  // kSpotChecks pixels of each tile a node sends, chosen here as it arrives (no node can know
  // which), rendered here and compared (cluster/tiles.h check_pixel): a node whose pixels are
  // finite but not the image's is caught where it changed the pixels checked (every tile it
  // changed throughout).
  void spot_check(const TileRect& r, const std::vector<float>& values);

  // The image phase's liveness: as keep_alive's, for the nodes rendering tiles and those joining
  // the image (watched from their READY, as in a run).
  void image_keep_alive(Clock::time_point now);

  // `p` renders no more of the image: its outstanding tiles go back (those it sent stay).
  void drop_from_image(Peer& p, const std::string& why);

  // The image is over (done, or failed): every node still rendering it is told so.
  void end_image();

  // The image's STOP (without image_follows): the node forgets the run.
  void stop_image(Peer& p);

  // ---- state ----

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

}  // namespace sirad::cluster::detail
