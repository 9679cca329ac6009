// sirad: the farm coordinator (see farm.h).
#include "farm/farm.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <thread>

#include <fmt/format.h>

#include "cluster/checkpoint.h"
#include "cluster/live_view.h"
#include "cluster/policy.h"
#include "cluster/rate_limit.h"
#include "cluster/result.h"
#include "coordinator/coordinator.h"
#include "io/results.h"
#include "io/write.h"
#include "io/write_gltf.h"
#include "proto/codec.h"
#include "proto/transport.h"
#include "scene/check.h"
#include "scene/encoding.h"
#include "scene/scene.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/limits.h"
#include "util/log.h"

namespace sirad::cli {

namespace fs = std::filesystem;

namespace {

void say(logging::Level level, const std::string& message, nlohmann::json fields) {
  logging::write(level, "sirad-coordinator", message, fields);
}

// The widest preview image of a running job (its height follows the job's aspect).
constexpr int kPreviewWidth = 480;
constexpr int kPreviewGlbShare = 10;  // see rc.preview

using Clock = std::chrono::steady_clock;

// Who is behind each node's routing id on the jobs' sockets (the key and address the farm's
// socket saw), for the jobs' runs (RunHooks::peer_identity): shared by the broker and the jobs' threads.
class PeerTable {
 public:
  void set(const std::string& local, cluster::PeerIdentity who) {
    std::lock_guard lock(mutex_);
    peers_[local] = std::move(who);
  }
  cluster::PeerIdentity get(const std::string& local) const {
    std::lock_guard lock(mutex_);
    auto it = peers_.find(local);
    return it == peers_.end() ? cluster::PeerIdentity{} : it->second;
  }
  void erase(const std::string& local) {
    std::lock_guard lock(mutex_);
    peers_.erase(local);
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::string, cluster::PeerIdentity> peers_;
};

// A job running on its thread. The broker reads `finished` and then `error`.
struct RunningJob {
  cluster::Job job;
  JobPlan plan;
  std::string endpoint;  // its run's inproc ROUTER socket
  std::atomic<bool> interrupt{false};  // set: checkpoint and stop (a cancel, or the farm stopping)
  std::atomic<bool> finished{false};
  std::string error;  // why it did not end done ("" when it did); written before `finished`
  std::thread thread;
};

// A node as the farm's socket sees it.
struct FarmNode {
  std::string local;      // its routing id on the jobs' sockets
  uint64_t job = 0;       // the job it is in (0: free)
  bool asked = false;     // free, asked to say HELLO for a job that started: not yet free for another
  std::unique_ptr<zmq::socket_t> dealer;  // to that job's socket, under `local`
  Clock::time_point heard;
};

// One run of `job` on `router`: from its checkpoint if it has one, else from its flags; its
// outputs in its folder, with a preview image as it runs. Returns the summary; throws
// sirad::Error when the run fails or is interrupted.
std::string run_job(zmq::socket_t& router, RunningJob& running, const std::string& folder, const FarmOptions& options,
                    FarmView& view, const PeerTable& peers) {
  const cluster::Job& job = running.job;
  const JobPlan& plan = running.plan;
  const fs::path dir(folder);
  const std::string checkpoint = (dir / "checkpoint").string();
  cluster::RunConfig rc;
  static_cast<cluster::ProcessSettings&>(rc) = options.process;
  rc.min_nodes = plan.min_nodes;
  rc.checkpoint = checkpoint;
  std::optional<wire::Checkpoint> resumed;
  if (fs::exists(checkpoint)) {
    resumed = cluster::read_checkpoint(checkpoint);
    static_cast<cluster::RunSettings&>(rc) = cluster::settings_of(*resumed);
    rc.resume = &*resumed;
  } else {
    static_cast<cluster::RunSettings&>(rc) = plan.settings;
  }
  const ImportOptions import = plan.output.import();
  rc.scene = job.scene.empty()
                 ? decode_scene(read_file_whole((dir / "scene.bin").string(), "scene", kMaxSceneBytes), "job scene")
                 : load_scene(job.scene, import);
  MeshOptions meshing = rc.mesh_options;  // refused before the mesh is made, should its flags ask for more
  meshing.max_patches = meshing.max_patches > 0 ? std::min<uint64_t>(meshing.max_patches, kFarmMaxPatches) : kFarmMaxPatches;
  PatchMesh mesh = mesh_scene(rc.scene, meshing);
  check_scene(rc.scene, mesh, camera_flag(plan.output.camera), "--camera");  // the view the images show
  rc.interrupt = &running.interrupt;
  rc.peer_identity = [&peers](const std::string& id) { return peers.get(id); };
  cluster::StatusReporter reporter(true, (dir / "status.json").string());
  rc.status = [&](const cluster::Status& s) {
    reporter(s);
    view.update(job.id, s);
  };
  rc.status_every_s = 0.25;
  OutputFlags output = plan.output;
  settle_image_size(output, rc.scene);
  const ResultOptions shown = result_options(output);
  rc.final_gather = final_gather_of(shown);  // the image's tiles rendered by the job's nodes
  const int preview_w = std::min(kPreviewWidth, shown.width);
  const int preview_h = std::max(1, static_cast<int>(std::lround(double(shown.height) * preview_w / shown.width)));
  const fs::path preview = dir / "preview.png";
  // Drawn on the run's loop: where the patches outnumber the preview's pixels, Gouraud corners
  // (a sight test per neighbour, corner_radiosity) would show nothing flat shading does not.
  const bool preview_flat = mesh.size() > static_cast<std::size_t>(preview_w) * static_cast<std::size_t>(preview_h);
  const Shading preview_shading = preview_flat ? Shading::flat : shown.shading;
  // The 3D view's preview (preview.glb) costs far more than the PNG (a ray scene, a sight test per
  // corner): it is written only once the time since the last one is kPreviewGlbShare times what
  // that one took, so that it holds the run's loop at most 1 / kPreviewGlbShare of the time.
  const fs::path preview_glb = dir / "preview.glb";
  auto glb_due = std::chrono::steady_clock::now();
  rc.preview = [&](const std::vector<glm::vec3>& radiosity) {
    try {
      const fs::path part = dir / "preview.png.part";
      write_png(part.string(), render_view(mesh, radiosity, *mesh.camera, preview_w, preview_h, preview_shading), shown.exposure);
      fs::rename(part, preview);
      const auto now = std::chrono::steady_clock::now();
      if (now >= glb_due) {
        write_glb(preview_glb.string(), mesh, radiosity, shown.exposure, static_cast<double>(shown.width) / shown.height);
        glb_due = now + kPreviewGlbShare * (std::chrono::steady_clock::now() - now);
      }
    } catch (const std::exception& e) {  // a preview that cannot be written must not end the run
      say(logging::Level::warn, fmt::format("job {}: preview not written: {}", job.id, e.what()), {{"event", "preview"}});
    }
  };
  auto start = std::chrono::steady_clock::now();
  cluster::RunResult result = cluster::coordinate(router, rc, mesh);
  reporter.finish();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_file_atomic((dir / "ledger.csv").string(), cluster::ledger_csv(result));  // kept should the image fail
  write_results((dir / job.name).string(), mesh, result.radiosity, shown,
                cluster::run_attributes(rc, cluster::outcome_of(result), mesh, job.scene.empty() ? job.name : job.scene, true),
                result.image ? &*result.image : nullptr, result.image_error);
  fs::remove(checkpoint);
  fs::remove(preview);
  fs::remove(preview_glb);
  if (result.bundles_lost) fail("{}", cluster::Policy::lost_reason(*result.bundles_lost));  // failed, its outputs kept
  return cluster::cluster_summary(result, mesh.size(), seconds);
}

// Sends `frames` on `socket` after `envelope` (a ROUTER's routing id), without waiting: false
// when it could not go (the peer is gone, or its queue is full).
bool forward(zmq::socket_t& socket, const std::string* envelope, const std::vector<std::string>& frames) {
  try {
    if (envelope && !socket.send(zmq::buffer(*envelope), zmq::send_flags::sndmore | zmq::send_flags::dontwait)) return false;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const auto more = i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none;
      if (!socket.send(zmq::buffer(frames[i]), more | zmq::send_flags::dontwait)) return false;
    }
    return true;
  } catch (const zmq::error_t&) {  // ROUTER_MANDATORY: no such peer
    return false;
  }
}

// The broker: the farm's socket, its nodes, its running jobs.
class Farm {
 public:
  Farm(zmq::context_t& context, zmq::socket_t& router, cluster::JobStore& store, const FarmOptions& options, FarmView& view)
      : context_(context), router_(router), store_(store), options_(options), view_(view),
        alive_(std::chrono::milliseconds(static_cast<int64_t>(options.process.heartbeat_ms) * options.process.liveness)) {
    router_.set(zmq::sockopt::router_handover, 1);  // a reconnecting node keeps its routing id
  }

  // Should serve() end by an exception (a job store that cannot be written), the running jobs
  // checkpoint and their threads end before the farm goes.
  ~Farm() {
    for (auto& [id, r] : jobs_) r->interrupt = true;
    for (auto& [id, r] : jobs_)
      if (r->thread.joinable()) r->thread.join();
  }

  void serve() {
    for (;;) {
      const bool stopping = options_.stop && options_.stop->load();
      for (auto& [id, r] : jobs_)
        if (stopping || store_.cancel_requested(id)) r->interrupt = true;
      reap(stopping);
      if (stopping && jobs_.empty()) return;
      forget_silent();
      if (!stopping) start_next();
      pump();
    }
  }

 private:
  // Ends the jobs whose threads have finished: their outcome to the store, their nodes free.
  void reap(bool stopping) {
    for (auto it = jobs_.begin(); it != jobs_.end();) {
      RunningJob& r = *it->second;
      if (!r.finished.load()) {
        ++it;
        continue;
      }
      r.thread.join();
      for (auto& [id, n] : nodes_)
        if (n.job == r.job.id) release(n);
      view_.ended(r.job.id);
      const uint64_t id = r.job.id;
      std::string state = "done", error;
      if (!r.error.empty()) {
        if (store_.cancel_requested(id)) {
          state = "cancelled", error = "cancelled while it ran";
          fs::remove(fs::path(store_.folder(id)) / "checkpoint");
          fs::remove(fs::path(store_.folder(id)) / "preview.png");
          fs::remove(fs::path(store_.folder(id)) / "preview.glb");
        } else if (stopping && r.interrupt.load()) {
          store_.stopped(id);  // queued: it resumes from its checkpoint at the next start
          say(logging::Level::info, fmt::format("job {} checkpointed; it resumes when the farm starts again", id),
              {{"event", "job stopped"}, {"job", id}});
          it = jobs_.erase(it);
          continue;
        } else {
          state = "failed", error = r.error;
        }
      }
      store_.finished(id, state, error, unix_now());
      say(state == "failed" ? logging::Level::warn : logging::Level::info,
          fmt::format("job {} ({}) {}{}", id, r.job.name, state, error.empty() ? "" : ": " + error),
          {{"event", "job " + state}, {"job", id}, {"error", error}});
      it = jobs_.erase(it);
    }
  }

  // Nodes silent for their liveness are forgotten (their job's run declares them dead too).
  void forget_silent() {
    const auto now = Clock::now();
    for (auto it = nodes_.begin(); it != nodes_.end();) {
      if (now - it->second.heard > alive_) {
        release(it->second);
        it = nodes_.erase(it);
      } else {
        ++it;
      }
    }
  }

  void release(FarmNode& n) {
    n.job = 0;
    n.dealer.reset();
    peers_.erase(n.local);
  }

  std::size_t free_nodes() const {
    return static_cast<std::size_t>(
        std::count_if(nodes_.begin(), nodes_.end(), [](const auto& n) { return n.second.job == 0 && !n.second.asked; }));
  }

  // The next queued job starts when a node is free; the free nodes are asked to say HELLO
  // (an ERROR `rejoin`), and their HELLOs join the jobs with room. A node asked is not free for
  // another job until its HELLO finds no room.
  void start_next() {
    if (free_nodes() == 0) return;
    std::optional<cluster::Job> job = store_.next();
    if (!job) return;
    auto r = std::make_unique<RunningJob>();
    r->job = *job;
    try {
      r->plan = plan_of(*job, fmt::format("job {}", job->id));
    } catch (const Error& e) {  // checked when submitted: only a job.json edited since gets here
      store_.started(job->id, unix_now());
      store_.finished(job->id, "failed", e.what(), unix_now());
      return;
    }
    r->endpoint = fmt::format("inproc://sirad-farm-job-{}", job->id);
    store_.started(job->id, unix_now());
    view_.started(job->id);
    say(logging::Level::info, fmt::format("job {} ({}) started", job->id, job->name),
        {{"event", "job started"}, {"job", job->id}, {"name", job->name}, {"runs", job->runs + 1}});
    RunningJob* p = r.get();
    const std::string folder = store_.folder(job->id);
    r->thread = std::thread([this, p, folder] {
      try {
        zmq::socket_t socket(context_, zmq::socket_type::router);
        socket.set(zmq::sockopt::linger, 0);
        socket.bind(p->endpoint);
        const std::string summary = run_job(socket, *p, folder, options_, view_, peers_);
        write_file_atomic((fs::path(folder) / "summary.txt").string(), summary);
      } catch (const std::exception& e) {
        p->error = e.what();
        if (p->error.empty()) p->error = "failed";
      }
      p->finished.store(true);
    });
    jobs_.emplace(job->id, std::move(r));
    for (auto& [id, n] : nodes_) {
      if (n.job != 0) continue;
      n.asked = true;
      wire::Error e;
      e.set_reason("a job starts; say HELLO to join it");
      e.set_rejoin(true);
      proto::send(router_, {proto::Command::error, e, {}}, &id);
    }
  }

  // The running job a HELLO joins: of the highest priority (the oldest first) that has room.
  RunningJob* job_with_room() {
    RunningJob* best = nullptr;
    for (auto& [id, r] : jobs_) {
      if (r->finished.load() || r->interrupt.load()) continue;
      const auto in = static_cast<uint32_t>(std::count_if(nodes_.begin(), nodes_.end(), [&](const auto& n) { return n.second.job == id; }));
      if (r->plan.max_nodes != 0 && in >= r->plan.max_nodes) continue;
      if (!best || r->job.priority > best->job.priority) best = r.get();  // jobs_ is by id: the oldest first
    }
    return best;
  }

  // Waits up to 100 ms for messages: a node's go to its job (or, for a free node, are answered
  // here), a job's go to its node.
  void pump() {
    std::vector<zmq::pollitem_t> items{{router_.handle(), 0, ZMQ_POLLIN, 0}};
    std::vector<std::string> owners;
    for (auto& [id, n] : nodes_)
      if (n.dealer) {
        items.push_back({n.dealer->handle(), 0, ZMQ_POLLIN, 0});
        owners.push_back(id);
      }
    try {
      zmq::poll(items, std::chrono::milliseconds(100));
    } catch (const zmq::error_t&) {  // a signal: the loop looks at the stop flag
      return;
    }
    for (std::size_t i = 1; i < items.size(); ++i) {
      if (!(items[i].revents & ZMQ_POLLIN)) continue;
      auto it = nodes_.find(owners[i - 1]);
      for (int k = 0; k < 64 && it != nodes_.end() && it->second.dealer; ++k) {  // what its job sent it
        auto frames = proto::receive(*it->second.dealer, 0);
        if (!frames) break;
        forward(router_, &it->first, *frames);
      }
    }
    if (items[0].revents & ZMQ_POLLIN)
      for (int k = 0; k < 256; ++k)
        if (!from_node()) break;
  }

  // One message from a node, if one is there.
  bool from_node() {
    std::string key;
    auto in = proto::receive(router_, 0, 1, kFarmMaxPatches, proto::kMaxChunks, &key);
    if (!in) return false;
    if (options_.peer_bytes) options_.peer_bytes->delivered(in->fd, in->frames_seen, in->bytes_seen);
    if (in->frames.size() < 2 || in->over) return true;  // a job could take none of it
    const std::string& id = in->frames.front();
    auto it = nodes_.find(id);
    if (it == nodes_.end()) {
      if (nodes_.size() >= kFarmMaxNodes) {
        // Room for a new node: the free one heard least recently is forgotten; none free: refused.
        auto oldest = nodes_.end();
        for (auto n = nodes_.begin(); n != nodes_.end(); ++n)
          if (n->second.job == 0 && (oldest == nodes_.end() || n->second.heard < oldest->second.heard)) oldest = n;
        if (oldest == nodes_.end()) return true;
        release(oldest->second);
        nodes_.erase(oldest);
      }
      it = nodes_.emplace(id, FarmNode{}).first;
      it->second.local = fmt::format("farm-node-{}", ++node_count_);
    }
    FarmNode& n = it->second;
    n.heard = Clock::now();
    const std::vector<std::string> message(in->frames.begin() + 1, in->frames.end());
    if (n.job != 0) {  // its job's run reads it (and refuses what is wrong, counting it)
      peers_.set(n.local, {key, in->address});
      forward(*n.dealer, nullptr, message);
      return true;
    }
    proto::Message m;
    try {
      m = proto::decode(message);
    } catch (const proto::ProtocolError&) {
      return true;  // a free node's garbage: no job to count it
    }
    if (m.command == proto::Command::hello) {
      n.asked = false;  // its answer: it joins a job with room, or is free for the next
      if (RunningJob* r = job_with_room()) {
        try {
          auto dealer = std::make_unique<zmq::socket_t>(context_, zmq::socket_type::dealer);
          dealer->set(zmq::sockopt::linger, 0);
          dealer->set(zmq::sockopt::routing_id, n.local);
          dealer->connect(r->endpoint);
          n.dealer = std::move(dealer);
          n.job = r->job.id;
        } catch (const zmq::error_t& e) {  // out of sockets or file descriptors: it waits, free
          uint64_t held = 0;
          if (join_log_.allow("join", std::chrono::duration<double>(Clock::now().time_since_epoch()).count(), &held))
            say(logging::Level::warn,
                fmt::format("a node cannot join job {}: {}{}", r->job.id, e.what(), held ? fmt::format(" ({} more held back)", held) : ""),
                {{"event", "join"}});
        }
      }
    }
    if (n.job != 0) {
      peers_.set(n.local, {key, in->address});
      forward(*n.dealer, nullptr, message);
    } else if (m.command == proto::Command::hello) {
      wire::Welcome w;  // no job with room: it waits
      proto::send(router_, {proto::Command::welcome, w, {}}, &id);
    } else if (m.command != proto::Command::heartbeat && m.command != proto::Command::error) {
      wire::Error e;
      e.set_reason(fmt::format("{} between jobs; say HELLO", proto::command_name(m.command)));
      e.set_rejoin(true);
      proto::send(router_, {proto::Command::error, e, {}}, &id);
    }
    return true;
  }

  zmq::context_t& context_;
  zmq::socket_t& router_;
  cluster::JobStore& store_;
  const FarmOptions& options_;
  FarmView& view_;
  const Clock::duration alive_;  // a node heard within this is there
  PeerTable peers_;
  std::map<uint64_t, std::unique_ptr<RunningJob>> jobs_;  // by id
  std::map<std::string, FarmNode> nodes_;                 // by the farm socket's routing id
  uint64_t node_count_ = 0;
  cluster::RateLimit join_log_{5, 10.0};  // lines about nodes that cannot join: 5 every 10 s
};

}  // namespace

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

JobPlan plan_job(const std::vector<std::string>& args) {
  CLI::App app{"job"};
  RunFlags run;
  JobPlan plan;
  add_run_flags(&app, run);
  add_output_flags(&app, plan.output);
  int min_nodes = 1, max_nodes = 0;
  app.add_option("--min-nodes", min_nodes, "Nodes ready before the job's first grant")->check(CLI::Range(1, static_cast<int>(cluster::kMaxJobNodes)));
  app.add_option("--max-nodes", max_nodes, "The most nodes the job takes; the others run other jobs (0: every node)")
      ->check(CLI::Range(0, static_cast<int>(cluster::kMaxJobNodes)));
  std::vector<const char*> argv{"job"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::Success&) {  // --help, --help-all, --version
    fail("job flags: a job cannot ask for help or the version (its flags are those of sirad-coordinator SCENE: see its --help)");
  } catch (const CLI::ExtrasError&) {
    std::string extra;  // CLI11's message lists them backwards
    for (const std::string& a : app.remaining()) extra += (extra.empty() ? "" : " ") + a;
    fail("job flags: not run or output flags: {}", extra);
  } catch (const CLI::ParseError& e) {
    fail("job flags: {}", e.what());
  }
  if (!plan.output.out.empty()) fail("job flags: --out: a job's outputs are named by the job");
  if (!plan.output.camera.empty()) camera_flag(plan.output.camera);  // checked now, not when the job runs
  if (plan.output.width > 0 && plan.output.height > 0) {  // (one side alone follows the scene's aspect when the job runs)
    int w = plan.output.width, h = plan.output.height;
    settle_image_size(w, h, std::nullopt);  // an image the outputs can hold
  }
  if (max_nodes != 0 && min_nodes > max_nodes) fail("job flags: --min-nodes {} is more than --max-nodes {}", min_nodes, max_nodes);
  plan.min_nodes = static_cast<uint32_t>(min_nodes);
  plan.max_nodes = static_cast<uint32_t>(max_nodes);
  plan.settings = settings_from(run, given_flags(&app));
  if (std::string why = cluster::target_error_problem(plan.settings); !why.empty()) fail("job flags: {}", why);
  if (plan.settings.mesh_options.target_patches > kFarmMaxPatches)
    fail("job flags: --patches {}: a farm takes jobs of at most {} patches", plan.settings.mesh_options.target_patches,
         kFarmMaxPatches);
  return plan;
}

cluster::JobRun job_run(const JobPlan& plan) {
  return {.settings = plan.settings, .output = output_args(plan.output), .min_nodes = plan.min_nodes, .max_nodes = plan.max_nodes};
}

JobPlan plan_of(const cluster::Job& job, const std::string& origin) {
  if (!job.run) return plan_job(job.args);
  JobPlan plan{.settings = job.run->settings, .min_nodes = job.run->min_nodes, .max_nodes = job.run->max_nodes};
  parse_output_args(job.run->output, plan.output, origin);
  if (!plan.output.camera.empty()) camera_flag(plan.output.camera);
  return plan;
}

void FarmView::started(uint64_t job) {
  std::lock_guard lock(mutex_);
  jobs_[job] = {};
}

void FarmView::update(uint64_t job, const cluster::Status& s) {
  std::lock_guard lock(mutex_);
  Running& r = jobs_[job];
  r.status = s;
  if (r.history.size() >= kMaxPoints) {  // keep every other point: the whole run at half the detail
    std::vector<Point> kept;
    for (std::size_t i = 0; i < r.history.size(); i += 2) kept.push_back(r.history[i]);
    r.history = std::move(kept);
  }
  r.history.push_back({s.elapsed_s, s.error_estimate, s.bundles_done});
}

void FarmView::ended(uint64_t job) {
  std::lock_guard lock(mutex_);
  jobs_.erase(job);
}

std::vector<uint64_t> FarmView::running() const {
  std::lock_guard lock(mutex_);
  std::vector<uint64_t> out;
  for (const auto& [id, r] : jobs_) out.push_back(id);
  return out;
}

std::optional<cluster::Status> FarmView::status(uint64_t job) const {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(job);
  return it == jobs_.end() ? std::nullopt : it->second.status;
}

std::vector<FarmView::Point> FarmView::history(uint64_t job) const {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(job);
  return it == jobs_.end() ? std::vector<Point>{} : it->second.history;
}

void serve_farm(zmq::context_t& context, zmq::socket_t& router, cluster::JobStore& store, const FarmOptions& options,
                FarmView& view) {
  Farm(context, router, store, options, view).serve();
}

}  // namespace sirad::cli
