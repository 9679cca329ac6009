// sirad: the coordinator's message loop over a ROUTER socket.
#include "coordinator/coordinator.h"

#include <chrono>
#include <cstdio>
#include <map>

#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/bundle.h"
#include "core/error.h"
#include "core/scene_io.h"
#include "proto/transport.h"

namespace sirad::cluster {

namespace {

using proto::Command;
using proto::Message;

struct Peer {
  uint32_t index = 0;
  std::string name;
  bool ready = false, stopped = false, final_in = false;
  uint64_t grant_id = 0;
  bool holds_grant = false;
  uint32_t exchange = 0;
  uint64_t bundles = 0;
  std::chrono::steady_clock::time_point last_seen = std::chrono::steady_clock::now();
};

class Coordinator {
 public:
  Coordinator(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh)
      : router_(router), config_(config), mesh_(mesh), ledger_(config.bundles),
        starts_(chunk_starts(static_cast<uint32_t>(mesh.size()), std::min<uint32_t>(config.chunks, static_cast<uint32_t>(mesh.size())))),
        aggregate_(starts_, 0), scene_bytes_(encode_scene(config.scene)) {
    run_.set_run_id(1);
    run_.set_scene_hash(mesh.hash);
    run_.set_seed(config.seed);
    run_.set_grid(static_cast<uint32_t>(config.grid == 0 ? auto_grid(mesh) : config.grid));
    run_.set_rule(to_string(config.rule));
    run_.set_burn_in(config.burn_in);
    for (std::size_t c = 0; c + 1 < starts_.size(); ++c) run_.add_chunk_starts(starts_[c]);
    run_.set_patches(static_cast<uint32_t>(mesh.size()));
    run_.set_exchange_every(config.exchange_every);
    run_.set_exchange_fraction(config.fraction);
    run_.set_topology(config.topology == Topology::star ? "star" : "ring");
    run_.set_mode(config.mode == Mode::sync ? "sync" : "async");
    run_.set_bundles(config.bundles);
    run_.set_target_patches(config.mesh_options.target_patches);
    run_.set_max_edge(config.mesh_options.max_edge);
  }

  RunResult run() {
    auto start = std::chrono::steady_clock::now();
    auto last_status = start;
    while (!done()) {
      if (config_.status && std::chrono::steady_clock::now() - last_status >= std::chrono::seconds(1)) {
        last_status = std::chrono::steady_clock::now();
        config_.status(snapshot(start));
      }
      if (config_.timeout_s > 0 &&
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > config_.timeout_s)
        fail("run did not finish within {} s ({} of {} bundles done)", config_.timeout_s, ledger_.done_count(),
             config_.bundles);
      if (config_.abort && config_.abort->load()) fail("run aborted: a local node failed");
      auto frames = proto::receive(router_, 100);
      if (!frames || frames->size() < 2) continue;
      std::string id = frames->front();
      if (auto it = peers_.find(id); it != peers_.end()) it->second.last_seen = std::chrono::steady_clock::now();
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
    if (config_.status) config_.status(snapshot(start));
    RunResult result;
    result.radiosity.resize(mesh_.size());
    for (uint32_t c = 0; c + 1 < starts_.size(); ++c) {
      std::vector<double> est = aggregate_.estimate(c);
      for (uint32_t j = starts_[c]; j < starts_[c + 1]; ++j) {
        std::size_t i = 3 * static_cast<std::size_t>(j - starts_[c]);
        result.radiosity[j] = glm::vec3(static_cast<float>(est[i]), static_cast<float>(est[i + 1]), static_cast<float>(est[i + 2]));
      }
    }
    for (const auto& [id, p] : peers_) result.nodes.push_back({p.name, p.bundles, p.exchange});
    result.exchange_bytes_in = bytes_in_;
    result.exchange_bytes_out = bytes_out_;
    result.exchanges = exchanges_;
    result.crossings = crossings_;
    result.grid = static_cast<int>(run_.grid());
    return result;
  }

 private:
  Status snapshot(std::chrono::steady_clock::time_point start) const {
    auto now = std::chrono::steady_clock::now();
    Status s;
    s.bundles_done = ledger_.done_count();
    s.bundles = config_.bundles;
    s.elapsed_s = std::chrono::duration<double>(now - start).count();
    for (const auto& [id, p] : peers_)
      {
      Status::Node n;
      n.name = p.name;
      n.bundles = p.bundles;
      n.exchanges = p.exchange;
      n.last_seen_s = std::chrono::duration<double>(now - p.last_seen).count();
      s.nodes.push_back(n);
    }
    return s;
  }

  bool done() const {
    if (!ledger_.finished() || peers_.empty()) return false;
    for (const auto& [id, p] : peers_)
      if (p.ready && !p.final_in) return false;
    return true;
  }

  void log(const std::string& id, const std::string& what) {
    std::fprintf(stderr, "sirad-coordinator: %s: %s\n", peer_name(id).c_str(), what.c_str());
  }
  std::string peer_name(const std::string& id) const {
    auto it = peers_.find(id);
    return it != peers_.end() ? it->second.name : "unknown peer";
  }
  void error(const std::string& id, const std::string& reason) {
    wire::Error e;
    e.set_reason(reason);
    proto::send(router_, {Command::error, e, {}}, &id);
  }

  void handle(const std::string& id, const Message& m) {
    if (m.command == Command::hello) return hello(id, std::get<wire::Hello>(m.header));
    auto it = peers_.find(id);
    if (it == peers_.end()) fail("{} before HELLO", proto::command_name(m.command));
    Peer& p = it->second;
    switch (m.command) {
      case Command::ready:
        p.ready = true;
        schedule();
        break;
      case Command::report: report(p, id, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::final_state: final_state(p, std::get<wire::Report>(m.header), m.bulk); break;
      case Command::error:
        if (config_.strict) fail("{}: {}", p.name, std::get<wire::Error>(m.header).reason());
        log(id, "node: " + std::get<wire::Error>(m.header).reason());
        break;
      case Command::heartbeat: break;
      default: fail("unexpected {}", proto::command_name(m.command));
    }
  }

  void hello(const std::string& id, const wire::Hello& h) {
    if (peers_.count(id)) return;  // an idle node repeats HELLO until it has a run
    Peer& p = peers_[id];
    p.index = aggregate_.nodes();
    p.name = h.node_name().empty() ? fmt::format("node {}", p.index) : h.node_name();
    aggregate_.add_node();
    wire::Welcome w;
    w.set_node_index(p.index);
    w.set_heartbeat_ms(1000);
    w.set_liveness(3);
    *w.mutable_run() = run_;
    proto::send(router_, {Command::welcome, w, {}}, &id);
    for (std::size_t off = 0; off < scene_bytes_.size() || off == 0; off += proto::kMaxSceneFrameBytes) {
      wire::SceneChunk c;
      c.set_scene_hash(mesh_.hash);
      c.set_total_bytes(scene_bytes_.size());
      c.set_offset(off);
      c.set_last(off + proto::kMaxSceneFrameBytes >= scene_bytes_.size());
      proto::send(router_, {Command::scene, c, {scene_bytes_.substr(off, proto::kMaxSceneFrameBytes)}}, &id);
      if (c.last()) break;
    }
  }

  // Grants: in async mode every ready node without a grant gets one at once; in sync mode only
  // when no ready node holds one (the barrier of the exchange period).
  void schedule() {
    uint32_t ready = 0;
    bool any_holding = false;
    for (const auto& [id, p] : peers_) {
      ready += p.ready && !p.stopped;
      any_holding = any_holding || (p.ready && p.holds_grant);
    }
    if (ready < config_.min_nodes) return;
    if (config_.mode == Mode::sync && any_holding) return;
    for (auto& [id, p] : peers_)
      if (p.ready && !p.stopped && !p.holds_grant) give_grant(id, p);
    if (ledger_.finished())
      for (auto& [id, p] : peers_)
        if (p.ready && !p.stopped && !p.holds_grant) {
          wire::Stop s;
          s.set_run_id(run_.run_id());
          proto::send(router_, {Command::stop, s, {}}, &id);
          p.stopped = true;
        }
  }

  void give_grant(const std::string& id, Peer& p) {
    uint64_t size = config_.exchange_every > 0 ? config_.exchange_every
                                               : std::max<uint64_t>(1, config_.bundles / (8 * std::max<uint32_t>(1, aggregate_.nodes())));
    auto ranges = ledger_.grant(p.index, size);
    if (ranges.empty()) return;
    wire::Grant g;
    g.set_run_id(run_.run_id());
    g.set_grant_id(++grants_);
    for (const Range& r : ranges) {
      auto* w = g.add_ranges();
      w->set_first(r.first);
      w->set_last(r.last);
    }
    if (config_.exchange_every > 0)
      for (uint32_t c : exchange_chunks(p.exchange, config_.fraction, aggregate_.chunks())) g.add_report_chunks(c);
    p.grant_id = g.grant_id();
    p.holds_grant = true;
    proto::send(router_, {Command::grant, g, {}}, &id);
  }

  void take_chunks(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    for (int i = 0; i < r.chunks_size(); ++i) {
      if (r.chunks(i) >= aggregate_.chunks()) fail("report names chunk {} of {}", r.chunks(i), aggregate_.chunks());
      aggregate_.set(p.index, r.chunks(i), proto::unpack(bulk[i]), r.counts(i));
      bytes_in_ += bulk[i].size();
    }
  }

  void report(Peer& p, const std::string& id, const wire::Report& r, const std::vector<std::string>& bulk) {
    if (!p.holds_grant || r.grant_id() != p.grant_id) fail("report for grant {} it does not hold", r.grant_id());
    for (const auto& d : r.done()) {
      ledger_.done(p.index, {d.first(), d.last()});
      p.bundles += d.last() - d.first();
    }
    take_chunks(p, r, bulk);
    crossings_ += r.crossings();
    if (config_.progress) config_.progress(ledger_.done_count(), config_.bundles);
    p.holds_grant = false;
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
      proto::send(router_, {Command::update, u, frames}, &id);
      ++p.exchange;
      ++exchanges_;
    }
    schedule();
  }

  void final_state(Peer& p, const wire::Report& r, const std::vector<std::string>& bulk) {
    if (!p.stopped || p.final_in) fail("FINAL without STOP");
    take_chunks(p, r, bulk);
    p.final_in = true;
  }

  zmq::socket_t& router_;
  const RunConfig& config_;
  const PatchMesh& mesh_;
  Ledger ledger_;
  std::vector<uint32_t> starts_;
  Aggregate aggregate_;
  std::string scene_bytes_;
  wire::Run run_;
  std::map<std::string, Peer> peers_;
  uint64_t grants_ = 0, bytes_in_ = 0, bytes_out_ = 0, crossings_ = 0;
  uint32_t exchanges_ = 0;
};

}  // namespace

Attributes run_attributes(const RunConfig& c, const RunResult& r, const PatchMesh& mesh, const std::string& scene) {
  return {
      {"sirad.version", std::string(SIRAD_VERSION)},
      {"sirad.scene", scene},
      {"sirad.scene_hash", mesh.hash},
      {"sirad.patches", static_cast<int64_t>(mesh.size())},
      {"sirad.bundles", static_cast<int64_t>(c.bundles)},
      {"sirad.grid", static_cast<int64_t>(r.grid)},
      {"sirad.seed", std::to_string(c.seed)},
      {"sirad.rule", std::string(to_string(c.rule))},
      {"sirad.nodes", static_cast<int64_t>(r.nodes.size())},
      {"sirad.exchange_every", c.exchange_every == 0 ? std::string("end") : std::to_string(c.exchange_every)},
      {"sirad.exchange_fraction", c.fraction},
      {"sirad.topology", std::string(c.topology == Topology::star ? "star" : "ring")},
      {"sirad.mode", std::string(c.mode == Mode::sync ? "sync" : "async")},
  };
}

std::string node_lines(const RunResult& r) {
  std::string out;
  for (const auto& n : r.nodes) out += fmt::format("node {}: {} bundles, {} exchanges\n", n.name, n.bundles, n.exchanges);
  return out;
}

RunResult coordinate(zmq::socket_t& router, const RunConfig& config, const PatchMesh& mesh) {
  return Coordinator(router, config, mesh).run();
}

}  // namespace sirad::cluster
