// sirad: the coordinator's image stage (session.h): the IMAGE and its tiles as the ImagePhase
// grants them, PIXELS checked and placed, nodes that join during the image, tiles rendered here.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "cluster/tiles.h"
#include "coordinator/session.h"
#include "util/limits.h"

namespace sirad::cluster::detail {

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
class Coordinator::ImageStage final : public Coordinator::Stage {
 public:
  ImageStage(Coordinator& c, RunResult& result) : c_(c), result_(result), began_(Clock::now()), header_(c.image_header()) {
    const GatherOptions& o = c_.config_.final_gather;
    // A resumed run none of whose nodes is here to render: min_nodes to join before the first tile.
    const bool none_here = std::none_of(c_.peers_.begin(), c_.peers_.end(), [&](const auto& e) { return c_.may_render(e.second); });
    const bool wait = none_here && c_.config_.resume != nullptr;
    c_.image_ = std::make_unique<ImagePhase>(o.width, o.height, o.spp, grant_deadlines(c_.config_), wait ? c_.config_.min_nodes : 0);
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
  void finish() override {
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

bool Coordinator::may_render(const Peer& p) const {
  const NodeState& n = policy_.node(p.index);
  return !n.dead && !n.quarantined && n.final_in;
}

void Coordinator::start_image(Peer& p, const wire::Image& h, const std::vector<std::string>& bulk) {
  grants_.clear(p.index);
  image_->join(p.index);
  send(p, {Command::image, h, bulk});
}

wire::Image Coordinator::image_header() const {
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

double Coordinator::spot_floor() const {
  double top = std::max({mesh_.background.x, mesh_.background.y, mesh_.background.z});
  for (const Material& m : mesh_.materials) top = std::max(top, static_cast<double>(std::max({m.emission.x, m.emission.y, m.emission.z})));
  return top * 1e-6;
}

void Coordinator::image_message(const proto::Received& in, const std::string& key, const wire::Image& h, const std::vector<std::string>& bulk) {
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

void Coordinator::join_image(const std::string& id, const std::string& key, const std::string& address, const Message& m) {
  auto before = peers_.find(id);
  const std::optional<uint32_t> index = before == peers_.end() ? std::nullopt : std::optional<uint32_t>(before->second.index);
  try {
    hello(id, key, address, std::get<wire::Hello>(m.header));
  } catch (const Error& e) {
    if (config_.strict) throw;
    log(id, e.what());
    error(id, e.what());
    return;
  }
  auto after = peers_.find(id);
  if (after != peers_.end() && (!index || after->second.index != *index)) after->second.image_joiner = true;
}

void Coordinator::joiner(Peer& p, const Message& m, const wire::Image& h, const std::vector<std::string>& bulk) {
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

void Coordinator::drop_joiner(Peer& p, const std::string& why) {
  policy_.dead(p.index);  // it holds no bundles: it joined during the image
  p.dead_why = why;
  p.down.clear();
  grants_.clear(p.index);
  log(p.id, fmt::format("dropped while joining the image ({})", why));
  error(p.id, why, true);
}

void Coordinator::grant_tiles(Peer& p, const TileGrant& g) { send(p, {Command::tiles, grant_of(g.id, g.tiles), {}}); }

void Coordinator::pixels(Peer& p, const wire::Pixels& px, const std::vector<std::string>& bulk) {
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

const FinalGather& Coordinator::here() {
  if (!here_) here_ = std::make_unique<FinalGather>(mesh_, *image_solution_, config_.final_gather);
  return *here_;
}

void Coordinator::spot_check(const TileRect& r, const std::vector<float>& values) {
  for (int k = 0; k < kSpotChecks; ++k) {
    const int x = r.x0 + static_cast<int>(spot_rng_() % static_cast<uint64_t>(r.x1 - r.x0));
    const int y = r.y0 + static_cast<int>(spot_rng_() % static_cast<uint64_t>(r.y1 - r.y0));
    const std::size_t i = (static_cast<std::size_t>(y - r.y0) * static_cast<std::size_t>(r.x1 - r.x0) + static_cast<std::size_t>(x - r.x0)) * 9;
    check_pixel(&values[i], here().render(*mesh_.camera, x, y, x + 1, y + 1), spot_floor_, x, y);
  }
}

void Coordinator::image_keep_alive(Clock::time_point now) {
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

void Coordinator::drop_from_image(Peer& p, const std::string& why) {
  image_->drop(p.index);
  log(p.id, fmt::format("dropped from the image ({}); its outstanding tiles are granted again", why));
  stop_image(p);
  if (std::optional<uint64_t> t = image_->poisoned())
    throw ImageFailed(fmt::format("tile {} was lost with {} nodes, each gone while it rendered the tile: it may crash whoever "
                                  "renders it, so it is not handed out again",
                                  *t, TilePlan::kMaxTileLosses));
}

void Coordinator::end_image() {
  for (auto& [id, p] : peers_)
    if (rendering(p)) {
      image_->drop(p.index);
      stop_image(p);
    }
}

void Coordinator::stop_image(Peer& p) {
  wire::Stop s;
  s.set_run_id(run_.run_id());
  send(p, {Command::stop, s, {}});
}

std::unique_ptr<Coordinator::Stage> Coordinator::image_stage(RunResult& result) { return std::make_unique<ImageStage>(*this, result); }

}  // namespace sirad::cluster::detail
