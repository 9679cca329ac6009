// sirad: the virtual-time cluster: a discrete-event loop around Policy (see emulate.h).
#include "cluster/emulate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <functional>
#include <memory>
#include <queue>

#include <unistd.h>

#include <fmt/format.h>

#include "cluster/exchange_choice.h"
#include "cluster/image_phase.h"
#include "cluster/worker.h"
#include "scene/encoding.h"
#include "solver/solver.h"
#include "util/error.h"

namespace sirad::cluster {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Every emulated node holds a solver's state: about 1 KB per patch (its estimates, sums and batch
// means; bench/RESULTS.md, "Scale"). Refused up front when that would not fit in half of this
// machine's memory, instead of failing an allocation halfway.
void check_memory(uint32_t nodes, std::size_t patches) {
  constexpr double kBytesPerPatch = 1100;
  const double need = static_cast<double>(nodes) * static_cast<double>(patches) * kBytesPerPatch;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page <= 0) return;
  const double have = static_cast<double>(pages) * static_cast<double>(page);
  if (need > have / 2)
    fail("emulate: {} nodes x {} patches need about {:.1f} GiB of solver state; this machine has {:.1f} GiB: use fewer "
         "nodes or patches",
         nodes, patches, need / (1 << 30), have / (1 << 30));
}

// The link seeds of the coordinator's own link (emulation::link_seed with an index no node has).
constexpr uint32_t kCoordinatorLinkIndex = 0xFFFFFFF0u;
// Bytes of a message carrying `patches` patches of chunk data (3 doubles each) and a header.
constexpr std::size_t kHeaderBytes = 64;
std::size_t message_bytes(std::size_t patches) { return kHeaderBytes + 24 * patches; }

// A message on its way to a node.
struct ToNode {
  enum Kind { grant, update, stop, tiles } kind = grant;
  GrantOrder grant_order;
  Exchange exchange;
  TileGrant tile_grant;
};

struct VNode {
  emulation::LinkSpec spec;
  double slowdown = 1;
  emulation::LinkModel up, down;
  std::unique_ptr<Worker> worker;  // the node's part, as a real node runs it
  std::deque<ToNode> inbox;   // delivered, not handled yet
  bool running = false;       // a grant is running
  bool granted = false;       // it has had a grant (idle counts from then)
  bool stopped = false;
  double idle_since = -1;     // waiting with nothing to run since then (< 0: not waiting)
  EmulatedNode figures;
};

class Emulator {
 public:
  Emulator(const EmulateConfig& config, const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots)
      : config_(config), run_(config.run), mesh_(mesh), engine_(engine), shots_(shots),
        policy_(make_policy(config.run, mesh, std::clamp(config.run.min_nodes, 1u, std::max(1u, config.nodes)), [this](const std::vector<uint32_t>& ready) { return choose(ready); })) {}

  EmulateResult run() {
    auto real_start = Clock::now();
    check_emulation(config_, mesh_.size());
    const uint32_t P = config_.nodes;
    if (run_.shots_per_bundle > 0 && shots_ == nullptr) fail("emulate: the first shot needs a shot engine");
    result_.bundle_s = config_.bundle_s > 0 ? config_.bundle_s
                                            : measure_bundle_seconds(mesh_, engine_, shots_, solver_options(run_, mesh_, P));
    const std::size_t scene_bytes = encode_scene(run_.scene).size();
    nodes_.resize(P);
    if (run_.profile && run_.profile->coordinator) {
      const emulation::LinkSpec& c = *run_.profile->coordinator;
      uint64_t seed = emulation::link_seed(run_.seed, kCoordinatorLinkIndex);
      coordinator_in_ = emulation::LinkModel(c.up_mbit, c.latency_ms, c.jitter_ms, c.loss, seed);
      coordinator_out_ = emulation::LinkModel(c.down_mbit, c.latency_ms, c.jitter_ms, c.loss, seed + 1);
    }
    for (uint32_t n = 0; n < P; ++n) {
      VNode& v = nodes_[n];
      v.figures.name = fmt::format("emu-{}", n);
      if (run_.profile) {
        v.spec = run_.profile->for_node(n, v.figures.name);
        v.slowdown = run_.profile->slowdown(v.spec);
        uint64_t seed = emulation::link_seed(run_.seed, n);
        v.down = emulation::LinkModel(v.spec.down_mbit, v.spec.latency_ms, v.spec.jitter_ms, v.spec.loss, seed);
        v.up = emulation::LinkModel(v.spec.up_mbit, v.spec.latency_ms, v.spec.jitter_ms, v.spec.loss, seed + 1);
      }
      v.figures.speed = v.spec.speed;
      v.figures.slowdown = v.slowdown;
      if (policy_.join() != n) fail("emulate: node index out of order");
      // WELCOME and the scene go out at 0; the node meshes (not timed), builds its solver (the
      // burn-in bundles, timed) and says READY.
      at(to_node_link(n, kHeaderBytes + scene_bytes), [this, n] { setup(n); });
    }
    run_events([this] { return policy_.done(); });
    if (!policy_.done()) fail("emulate: the run stalled at {:.3f} s with {} of {} bundles done", now_, policy_.ledger().done_count(), run_.bundles);
    const double solved_s = now_;

    result_.wall_s = solved_s;
    result_.error_estimate = policy_.error_estimate();
    RunResult& r = result_.run;
    RunResult known = policy_result(policy_, run_grid(run_, mesh_));
    known.exchange_bytes_in = r.exchange_bytes_in;
    known.exchange_bytes_out = r.exchange_bytes_out;
    known.final_bytes = r.final_bytes;
    known.crossings = r.crossings;
    known.seconds = solved_s;
    r = std::move(known);
    if (run_.final_gather.spp > 0 && mesh_.camera) image();
    for (uint32_t n = 0; n < P; ++n) {
      EmulatedNode& f = nodes_[n].figures;
      f.bundles = policy_.node(n).bundles;
      f.exchanges = policy_.node(n).exchanges;
      f.utilisation = result_.wall_s > 0 ? f.busy_s / result_.wall_s : 0.0;
      r.nodes.push_back({f.name, f.bundles, f.exchanges, f.busy_s, f.idle_s, false, "", false, f.tiles});
      result_.nodes.push_back(f);
    }
    result_.real_s = seconds_since(real_start);
    return std::move(result_);
  }

 private:
  struct Event {
    double t;
    uint64_t seq;  // ties in time keep the order they were scheduled in
    std::function<void()> fn;
    bool operator>(const Event& o) const { return t != o.t ? t > o.t : seq > o.seq; }
  };

  // --exchange-every auto, as the real coordinator decides it (Coordinator::choose): each
  // node's bundle time (its READY there) and its link's transfer time.
  ExchangeSetting choose(const std::vector<uint32_t>& ready) {
    std::vector<NodeCost> costs;
    for (uint32_t n : ready)
      costs.push_back({result_.bundle_s * nodes_[n].slowdown, exchange_seconds(mesh_.size(), run_.profile ? &nodes_[n].spec : nullptr)});
    const double hub = run_.profile && run_.profile->coordinator ? coordinator_seconds(mesh_.size(), *run_.profile->coordinator) : 0;
    ExchangeSetting s = auto_setting(run_, mesh_, costs, policy_.aggregate().chunks(), &engine_, hub);
    result_.exchange_why = s.why;
    return s;
  }

  void at(double t, std::function<void()> fn) { events_.push({t, seq_++, std::move(fn)}); }

  // The events in time order, each advancing the virtual clock to its time, until `done` or none
  // is left.
  void run_events(const std::function<bool()>& done) {
    while (!events_.empty() && !done()) {
      Event e = events_.top();
      events_.pop();
      now_ = e.t;
      e.fn();
    }
  }

  // When a message of `bytes` sent now reaches the coordinator from node n, or node n from the
  // coordinator: it crosses the node's link and the coordinator's, which every node shares
  // (both carry it at once, as a switch forwards packets; it is in when both have).
  double to_coordinator_link(uint32_t n, std::size_t bytes) {
    return std::max(nodes_[n].up.deliver(now_, bytes), coordinator_in_.deliver(now_, bytes));
  }
  double to_node_link(uint32_t n, std::size_t bytes) {
    return std::max(nodes_[n].down.deliver(now_, bytes), coordinator_out_.deliver(now_, bytes));
  }
  void log(uint32_t n, const char* what, uint64_t bundles) { result_.timeline.push_back({now_, n, what, bundles}); }
  double cost(uint32_t n, uint64_t bundles) const { return static_cast<double>(bundles) * result_.bundle_s * nodes_[n].slowdown; }

  std::size_t patches_of(const std::vector<uint32_t>& chunks) const {
    std::size_t p = 0;
    for (uint32_t c : chunks) p += policy_.aggregate().chunk_size(c);
    return p;
  }

  // --- the node side ---

  void setup(uint32_t n) {
    VNode& v = nodes_[n];
    const std::vector<uint32_t>& starts = policy_.starts();  // with the end
    v.worker = std::make_unique<Worker>(mesh_, engine_, shots_, run_, n, std::span(starts.data(), starts.size() - 1));
    // READY leaves when the burn-in is done (and only then takes its place on the shared link).
    at(now_ + cost(n, static_cast<uint64_t>(v.worker->solver().burn_in())),
       [this, n] { at(to_coordinator_link(n, kHeaderBytes), [this, n] { ready(n); }); });
  }

  void to_node(uint32_t n, ToNode m, std::size_t bytes) {
    at(to_node_link(n, bytes), [this, n, m = std::move(m)]() mutable {
      VNode& v = nodes_[n];
      if (v.idle_since >= 0) {
        v.figures.idle_s += now_ - v.idle_since;
        v.idle_since = -1;
      }
      v.inbox.push_back(std::move(m));
      work(n);
    });
  }

  // Handles the node's messages in order until it runs a grant, stops, or has none left; once
  // stopped, only the image's.
  void work(uint32_t n) {
    VNode& v = nodes_[n];
    while (!v.running && !v.inbox.empty()) {
      ToNode m = std::move(v.inbox.front());
      v.inbox.pop_front();
      if (m.kind == ToNode::tiles) {
        render_tiles(n, std::move(m.tile_grant));
      } else if (v.stopped) {
        continue;  // the solve's, after its FINAL: nothing to do
      } else if (m.kind == ToNode::update) {
        for (std::size_t i = 0; i < m.exchange.chunks.size(); ++i) {
          const Aggregate::Part& part = m.exchange.parts[i];
          v.worker->absorb(m.exchange.chunks[i], part.sum, part.count);
        }
      } else if (m.kind == ToNode::stop) {
        v.stopped = true;
        std::vector<ChunkState> chunks = v.worker->all_states();
        at(to_coordinator_link(n, message_bytes(mesh_.size())), [this, n, chunks = std::move(chunks)]() mutable {
          policy_.final_state(n, std::move(chunks));
          nodes_[n].figures.end_s = now_;
          log(n, "final", policy_.aggregate().chunks());
        });
      } else {
        run_grant(n, std::move(m.grant_order));
      }
    }
    if (!v.running && !v.stopped && v.granted && v.idle_since < 0) v.idle_since = now_;
  }

  // The grant's bundles run now, for real; the REPORT leaves when their virtual time is up.
  void run_grant(uint32_t n, GrantOrder g) {
    VNode& v = nodes_[n];
    v.running = v.granted = true;
    uint64_t count = 0, crossings = v.worker->solver().crossings();
    v.worker->run(g.ranges);
    for (const Range& r : g.ranges) count += r.size();
    result_.run.crossings += v.worker->solver().crossings() - crossings;
    double busy = cost(n, count);
    double error = v.worker->reported_error();
    std::vector<ChunkState> chunks = v.worker->states(g.report_chunks);
    at(now_ + busy, [this, n, g = std::move(g), chunks = std::move(chunks), busy, error, count]() mutable {
      VNode& v = nodes_[n];
      v.running = false;
      v.figures.busy_s += busy;
      std::size_t bytes = message_bytes(patches_of(g.report_chunks)) + 16 * g.ranges.size();
      at(to_coordinator_link(n, bytes), [this, n, g = std::move(g), chunks = std::move(chunks), error, count]() mutable {
        report(n, g, std::move(chunks), error, count);
      });
      work(n);
    });
  }

  // The grant's tiles are rendered now, for real; the PIXELS leaves when their virtual time is up.
  void render_tiles(uint32_t n, TileGrant g) {
    VNode& v = nodes_[n];
    v.running = true;
    std::vector<std::string> frames;
    double busy = 0;
    for (const Range& r : g.tiles)
      for (uint64_t t = r.first; t < r.last; ++t) {
        const TileRect rect = image_->grid().rect(t);
        frames.push_back(pack_tile(gather_->render(*mesh_.camera, rect.x0, rect.y0, rect.x1, rect.y1)));
        const double whole = static_cast<double>(ImagePhase::kTileSide) * ImagePhase::kTileSide;
        busy += result_.tile_s * v.slowdown * static_cast<double>(rect.pixels()) / whole;
      }
    at(now_ + busy, [this, n, g = std::move(g), frames = std::move(frames), busy]() mutable {
      VNode& v = nodes_[n];
      v.running = false;
      std::size_t bytes = kHeaderBytes + 16 * g.tiles.size();
      for (const std::string& f : frames) bytes += f.size();
      at(to_coordinator_link(n, bytes), [this, n, g = std::move(g), frames = std::move(frames), busy]() mutable {
        pixels(n, g, frames, busy);
      });
      work(n);
    });
  }

  // --- the coordinator side ---

  // The image phase, after every FINAL is in: the nodes get the IMAGE (the solution) and tiles
  // as the real coordinator grants them, until every tile is placed.
  void image() {
    const GatherOptions& o = run_.final_gather;
    RunResult& r = result_.run;
    gather_ = std::make_unique<FinalGather>(mesh_, r.radiosity, o);
    result_.tile_s = config_.tile_s > 0 ? config_.tile_s : measure_tile_seconds(*gather_, *mesh_.camera);
    image_ = std::make_unique<ImagePhase>(o.width, o.height, o.spp, grant_deadlines(run_), 0);
    const double began = now_;
    for (uint32_t n = 0; n < nodes_.size(); ++n) {
      log(n, "image", 0);
      image_->join(n);
      nodes_[n].down.deliver(now_, message_bytes(mesh_.size()));  // the IMAGE takes its place on the link
      coordinator_out_.deliver(now_, message_bytes(mesh_.size()));
    }
    grant_tiles();
    run_events([this] { return image_->finished(); });
    if (!image_->finished()) fail("emulate: the image stalled at {:.3f} s with {} of {} tiles done", now_, image_->tiles_done(), image_->tiles());
    r.image = std::move(image_->passes());
    r.image_tiles = image_->tiles();
    r.image_seconds = now_ - began;
    for (uint32_t n = 0; n < nodes_.size(); ++n) nodes_[n].figures.tiles = image_->tiles_by(n);
  }

  void grant_tiles() {
    for (ImagePhase::Order& o : image_->next_work(now_)) {
      uint64_t tiles = 0;
      for (const Range& r : o.grant.tiles) tiles += r.size();
      log(o.node, "tiles", tiles);
      const std::size_t bytes = kHeaderBytes + 16 * o.grant.tiles.size();
      ToNode m{.kind = ToNode::tiles};
      m.tile_grant = std::move(o.grant);
      to_node(o.node, std::move(m), bytes);
    }
  }

  void pixels(uint32_t n, const TileGrant& g, const std::vector<std::string>& frames, double busy) {
    log(n, "pixels", frames.size());
    image_->take_result(n, g.id, g.tiles, frames, busy, kMaxSeconds, now_, nullptr);
    grant_tiles();
  }

  void ready(uint32_t n) {
    log(n, "ready", 0);
    nodes_[n].figures.ready_s = now_;
    policy_.ready(n);
    policy_.set_bundle_time(n, cost(n, 1));
    dispatch();
  }

  void report(uint32_t n, const GrantOrder& g, std::vector<ChunkState> chunks, double error, uint64_t count) {
    log(n, "report", count);
    std::optional<Exchange> x = policy_.take_result(n, g.id, g.ranges, std::move(chunks), error);
    if (x) {
      result_.run.exchange_bytes_in += 24 * patches_of(x->chunks);
      result_.run.exchange_bytes_out += 24 * patches_of(x->chunks);
      log(n, "update", x->chunks.size());
      std::size_t bytes = message_bytes(patches_of(x->chunks));
      to_node(n, {ToNode::update, {}, std::move(*x)}, bytes);
    }
    policy_.check_close(now_);
    dispatch();
  }

  void dispatch() {
    Orders orders = policy_.next_work();
    for (GrantOrder& g : orders.grants) {
      uint64_t bundles = 0;
      for (const Range& r : g.ranges) bundles += r.size();
      log(g.node, "grant", bundles);
      std::size_t bytes = kHeaderBytes + 16 * g.ranges.size() + 4 * g.report_chunks.size();
      uint32_t node = g.node;
      to_node(node, {ToNode::grant, std::move(g), {}}, bytes);
    }
    for (uint32_t n : orders.stops) {
      log(n, "stop", 0);
      result_.run.final_bytes += 24 * mesh_.size();
      to_node(n, {ToNode::stop, {}, {}}, kHeaderBytes);
    }
  }

  const EmulateConfig& config_;
  const RunConfig& run_;
  const PatchMesh& mesh_;
  BundleEngine& engine_;
  ShotEngine* shots_;
  Policy policy_;
  std::vector<VNode> nodes_;
  emulation::LinkModel coordinator_in_, coordinator_out_;  // the profile's coordinator link (unshaped without one)
  std::priority_queue<Event, std::vector<Event>, std::greater<Event>> events_;
  uint64_t seq_ = 0;
  double now_ = 0;
  EmulateResult result_;
  std::unique_ptr<FinalGather> gather_;  // the image's, shared by the nodes (a pixel depends on its place only)
  std::unique_ptr<ImagePhase> image_;
};

}  // namespace

void check_emulation(const EmulateConfig& c, std::size_t patches) {
  if (c.nodes == 0) fail("emulate: --nodes must be at least 1");
  check_memory(c.nodes, patches);
  if (!c.run.profile) return;
  for (uint32_t n = 0; n < c.nodes; ++n) {
    emulation::LinkSpec spec = c.run.profile->for_node(n, fmt::format("emu-{}", n));
    if (spec.disconnect_at_s >= 0)
      fail("emulate: profile{}: node emu-{} disconnects at {} s: disconnects are not emulated in virtual time (use sirad render --nodes)",
           c.run.profile->name.empty() ? "" : " " + c.run.profile->name, n, spec.disconnect_at_s);
  }
}

double measure_bundle_seconds(const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots, const SolverOptions& options,
                              int steps) {
  SolverOptions o = options;
  o.track_error = false;
  Solver solver(mesh, engine, o, shots);
  std::vector<double> t;
  for (int i = 0; i < std::max(1, steps); ++i) {
    auto t0 = Clock::now();
    solver.step(static_cast<uint64_t>(i));
    t.push_back(seconds_since(t0));
  }
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  return t[t.size() / 2];
}

double measure_tile_seconds(const FinalGather& gather, const Camera& camera, int renders) {
  const GatherOptions& o = gather.options();
  const int side = ImagePhase::kTileSide;
  const int x0 = std::max(0, o.width / 2 - side / 2), y0 = std::max(0, o.height / 2 - side / 2);
  const int x1 = std::min(o.width, x0 + side), y1 = std::min(o.height, y0 + side);
  std::vector<double> t;
  for (int i = 0; i < std::max(1, renders); ++i) {
    auto t0 = Clock::now();
    gather.render(camera, x0, y0, x1, y1);
    t.push_back(seconds_since(t0));
  }
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  // A tile cut at the image's edge: scaled to a whole one.
  return t[t.size() / 2] * static_cast<double>(side) * side / (static_cast<double>(x1 - x0) * (y1 - y0));
}

EmulateResult emulate(const EmulateConfig& config, const PatchMesh& mesh, BundleEngine& engine, ShotEngine* shots) {
  return Emulator(config, mesh, engine, shots).run();
}

std::string nodes_csv(const EmulateResult& r) {
  std::string out = "node,speed,slowdown,bundles,exchanges,ready_s,busy_s,idle_s,utilisation,end_s\n";
  for (const EmulatedNode& n : r.nodes)
    out += fmt::format("{},{},{},{},{},{:.6f},{:.6f},{:.6f},{:.4f},{:.6f}\n", n.name, n.speed, n.slowdown, n.bundles,
                       n.exchanges, n.ready_s, n.busy_s, n.idle_s, n.utilisation, n.end_s);
  return out;
}

std::string timeline_csv(const EmulateResult& r) {
  std::string out = "t,node,event,bundles\n";
  for (const TimelineEvent& e : r.timeline) out += fmt::format("{:.9f},{},{},{}\n", e.t, e.node, e.what, e.bundles);
  return out;
}

}  // namespace sirad::cluster
