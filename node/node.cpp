// sirad: the worker node's loop (proto/PROTOCOL.md sections 3.1 to 3.3).
#include "node/node.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <random>

#include <fmt/format.h>

#include "core/bundle_cl.h"
#include "core/error.h"
#include "core/mesh.h"
#include "core/scene_io.h"
#include "core/solver.h"
#include "proto/transport.h"

namespace sirad::node {

namespace {

using proto::Command;
using proto::Message;

// One run on this node: the mesh, the engine and the solver, and the run's chunks.
struct RunState {
  wire::Run run;
  uint32_t index = 0;
  PatchMesh mesh;
  std::unique_ptr<BundleEngine> engine;
  std::unique_ptr<Solver> solver;
};

class Node {
 public:
  Node(zmq::context_t& context, const std::string& endpoint, const NodeOptions& options)
      : socket_(context, zmq::socket_type::dealer), options_(options) {
    std::random_device rd;
    socket_.set(zmq::sockopt::routing_id, fmt::format("node-{:08x}{:08x}", rd(), rd()));
    socket_.set(zmq::sockopt::linger, 0);
    socket_.connect(endpoint);
  }

  void serve() {
    auto last_hello = std::chrono::steady_clock::now();
    hello();
    while (!(options_.stop && options_.stop->load())) {
      // Without a run, say HELLO again every second: a coordinator that starts (or restarts)
      // later hears of this node that way.
      if (!state_ && !pending_ && std::chrono::steady_clock::now() - last_hello > std::chrono::seconds(1)) {
        hello();
        last_hello = std::chrono::steady_clock::now();
      }
      auto frames = proto::receive(socket_, options_.poll_ms);
      if (!frames) continue;
      Message m;
      try {
        m = proto::decode(*frames);
      } catch (const proto::ProtocolError& e) {
        std::fprintf(stderr, "sirad-node %s: refused a message: %s\n", options_.name.c_str(), e.what());
        continue;
      }
      if (m.command == Command::bye) return;
      handle(m);
    }
  }

 private:
  void hello() {
    wire::Hello h;
    h.set_node_name(options_.name);
    h.set_sirad_version("0.1.0");
    proto::send(socket_, {Command::hello, h, {}});
  }

  void handle(const Message& m) {
    switch (m.command) {
      case Command::welcome: welcome(std::get<wire::Welcome>(m.header)); break;
      case Command::scene: scene(std::get<wire::SceneChunk>(m.header), m.bulk[0]); break;
      case Command::grant: grant(std::get<wire::Grant>(m.header)); break;
      case Command::update: update(std::get<wire::Update>(m.header), m.bulk); break;
      case Command::stop: stop(); break;
      case Command::error:
        std::fprintf(stderr, "sirad-node %s: coordinator: %s\n", options_.name.c_str(),
                     std::get<wire::Error>(m.header).reason().c_str());
        break;
      default: error(fmt::format("unexpected {}", proto::command_name(m.command)));
    }
  }

  void error(const std::string& reason) {
    wire::Error e;
    e.set_reason(reason);
    proto::send(socket_, {Command::error, e, {}});
  }

  void welcome(const wire::Welcome& w) {
    if (!w.has_run()) return;
    state_.reset();
    pending_ = std::make_unique<RunState>();
    pending_->run = w.run();
    pending_->index = w.node_index();
    scene_bytes_.clear();
  }

  // Scene chunks in order; the last one completes the scene: mesh it, check the hash, start.
  void scene(const wire::SceneChunk& c, const std::string& bytes) {
    if (!pending_ || c.offset() != scene_bytes_.size()) return error("SCENE out of order");
    scene_bytes_ += bytes;
    if (!c.last()) return;
    try {
      const wire::Run& run = pending_->run;
      Scene scene = decode_scene(scene_bytes_, "scene from coordinator");
      MeshOptions mo;
      mo.target_patches = run.target_patches();
      mo.max_edge = run.max_edge();
      pending_->mesh = mesh_scene(scene, mo);
      if (pending_->mesh.hash != run.scene_hash())
        fail("meshed scene hash {} differs from the run's {}", pending_->mesh.hash, run.scene_hash());
      pending_->engine = make_cl_engine(pending_->mesh, {.device = options_.device});
      SolverOptions so;
      so.seed = run.seed();
      so.grid = static_cast<int>(run.grid());
      so.rule = parse_update_rule(run.rule());
      so.burn_in = run.burn_in();
      so.chain_id = pending_->index;
      auto t0 = std::chrono::steady_clock::now();
      pending_->solver = std::make_unique<Solver>(pending_->mesh, *pending_->engine, so);
      double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() /
                  std::max(1, pending_->solver->burn_in());
      state_ = std::move(pending_);
      wire::Ready ready;
      ready.set_run_id(state_->run.run_id());
      ready.set_scene_hash(state_->mesh.hash);
      ready.set_ms_per_bundle(ms);
      proto::send(socket_, {Command::ready, ready, {}});
    } catch (const Error& e) {
      error(e.what());
      pending_.reset();
    }
  }

  // Run the granted bundles, then report the chunks the grant names.
  void grant(const wire::Grant& g) {
    if (!state_ || g.run_id() != state_->run.run_id()) return error("GRANT for no run of mine");
    wire::Report report;
    report.set_run_id(g.run_id());
    report.set_grant_id(g.grant_id());
    uint64_t crossings = state_->solver->crossings();
    for (const auto& r : g.ranges()) {
      for (uint64_t k = r.first(); k < r.last(); ++k) state_->solver->step(k);
      *report.add_done() = r;
    }
    report.set_crossings(state_->solver->crossings() - crossings);
    Message m{Command::report, {}, chunk_frames(g.report_chunks(), report)};
    m.header = report;
    proto::send(socket_, m);
  }

  // The node's (sum, count) of the named chunks into the report and its bulk frames.
  template <typename Chunks>
  std::vector<std::string> chunk_frames(const Chunks& chunks, wire::Report& report) {
    std::vector<std::string> bulk;
    const auto& starts = state_->run.chunk_starts();
    const auto& sum = state_->solver->sum();
    for (uint32_t c : chunks) {
      uint32_t first = starts[c], last = c + 1 < static_cast<uint32_t>(starts.size()) ? starts[c + 1] : state_->run.patches();
      std::vector<double> v;
      v.reserve(3 * (last - first));
      for (uint32_t j = first; j < last; ++j) {
        v.push_back(sum[j].x);
        v.push_back(sum[j].y);
        v.push_back(sum[j].z);
      }
      report.add_chunks(c);
      report.add_counts(state_->solver->bundles());
      bulk.push_back(proto::pack(v));
    }
    return bulk;
  }

  void update(const wire::Update& u, const std::vector<std::string>& bulk) {
    if (!state_ || u.run_id() != state_->run.run_id()) return;
    const auto& starts = state_->run.chunk_starts();
    for (int i = 0; i < u.chunks_size(); ++i) {
      uint32_t c = u.chunks(i);
      if (c >= static_cast<uint32_t>(starts.size())) return error("UPDATE names an unknown chunk");
      uint32_t first = starts[c];
      std::vector<double> v = proto::unpack(bulk[i]);
      std::vector<glm::dvec3> others(v.size() / 3);
      for (std::size_t j = 0; j < others.size(); ++j) others[j] = glm::dvec3(v[3 * j], v[3 * j + 1], v[3 * j + 2]);
      try {
        state_->solver->absorb(first, others, u.counts(i));
      } catch (const Error& e) {
        return error(e.what());
      }
    }
  }

  void stop() {
    if (!state_) return;
    wire::Report final_state;
    final_state.set_run_id(state_->run.run_id());
    std::vector<uint32_t> all(state_->run.chunk_starts_size());
    for (uint32_t c = 0; c < all.size(); ++c) all[c] = c;
    Message m{Command::final_state, {}, chunk_frames(all, final_state)};
    m.header = final_state;
    proto::send(socket_, m);
    state_.reset();
  }

  zmq::socket_t socket_;
  NodeOptions options_;
  std::unique_ptr<RunState> pending_, state_;
  std::string scene_bytes_;
};

}  // namespace

void serve(zmq::context_t& context, const std::string& endpoint, const NodeOptions& options) {
  Node(context, endpoint, options).serve();
}

}  // namespace sirad::node
