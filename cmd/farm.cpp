// sirad: the farm coordinator (see farm.h).
#include "cmd/farm.h"

#include <chrono>
#include <filesystem>
#include <map>
#include <thread>

#include <fmt/format.h>

#include "cluster/checkpoint.h"
#include "cluster/live_view.h"
#include "cluster/result.h"
#include "coordinator/coordinator.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/log.h"
#include "core/results.h"
#include "core/scene.h"
#include "core/scene_io.h"
#include "proto/codec.h"
#include "proto/transport.h"

namespace sirad::cli {

namespace fs = std::filesystem;

namespace {

void say(logging::Level level, const std::string& message, nlohmann::json fields) {
  logging::write(level, "sirad-coordinator", message, fields);
}

// The largest scene file a job's folder may hold (decode_scene's own bound is the same).
constexpr std::size_t kMaxSceneBytes = std::size_t{1} << 31;

using Clock = std::chrono::steady_clock;

// The nodes heard between jobs (routing id -> when), so a job starts only with a node there.
using IdleNodes = std::map<std::string, Clock::time_point>;

// Between jobs: HELLO gets a WELCOME without a run (the node waits for the next), anything
// else from a node of an ended job an ERROR asking it to say HELLO; for `ms` at most. A node
// heard is noted in `idle_nodes` (at most kMaxIdleNodes: the oldest is forgotten).
constexpr std::size_t kMaxIdleNodes = 4096;
void idle(zmq::socket_t& router, int ms, IdleNodes& idle_nodes) {
  auto in = proto::receive(router, ms, 1, 0, 0);
  if (!in || in->frames.size() < 2 || in->over) return;
  const std::string id = in->frames.front();
  if (idle_nodes.size() >= kMaxIdleNodes && !idle_nodes.count(id))
    idle_nodes.erase(std::min_element(idle_nodes.begin(), idle_nodes.end(),
                                      [](const auto& a, const auto& b) { return a.second < b.second; }));
  idle_nodes[id] = Clock::now();
  proto::Message m;
  try {
    m = proto::decode({in->frames.begin() + 1, in->frames.end()});
  } catch (const proto::ProtocolError&) {
    return;
  }
  if (m.command == proto::Command::hello) {
    wire::Welcome w;
    proto::send(router, {proto::Command::welcome, w, {}}, &id);
  } else if (m.command != proto::Command::heartbeat && m.command != proto::Command::error) {
    wire::Error e;
    e.set_reason(fmt::format("{} between jobs; say HELLO", proto::command_name(m.command)));
    e.set_rejoin(true);
    proto::send(router, {proto::Command::error, e, {}}, &id);
  }
}

// One run of `job`: from its checkpoint if it has one, else from its flags; its outputs in its
// folder. Returns the summary; throws sirad::Error when the run fails or is interrupted.
std::string run_job(zmq::socket_t& router, const cluster::Job& job, const std::string& folder, const FarmOptions& options,
                    FarmView& view) {
  const fs::path dir(folder);
  const std::string checkpoint = (dir / "checkpoint").string();
  JobPlan plan = plan_job(job.args);
  cluster::RunConfig rc;
  static_cast<cluster::ProcessSettings&>(rc) = options.process;
  rc.checkpoint = checkpoint;
  std::optional<wire::Checkpoint> resumed;
  if (fs::exists(checkpoint)) {
    resumed = cluster::read_checkpoint(checkpoint);
    static_cast<cluster::RunSettings&>(rc) = cluster::settings_of(*resumed);
    rc.resume = &*resumed;
  } else {
    static_cast<cluster::RunSettings&>(rc) = plan.settings;
  }
  ImportOptions import{.skip_degenerate = plan.output.skip_degenerate, .two_sided = plan.output.two_sided};
  rc.scene = job.scene.empty()
                 ? decode_scene(read_file_whole((dir / "scene.bin").string(), "scene", kMaxSceneBytes), "job scene")
                 : load_scene(job.scene, import);
  PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
  if (mesh.size() > kFarmMaxPatches) fail("{} patches: a farm takes jobs of at most {}", mesh.size(), kFarmMaxPatches);
  rc.interrupt = options.interrupt;
  cluster::StatusReporter reporter(true, (dir / "status.json").string());
  rc.status = [&](const cluster::Status& s) {
    reporter(s);
    view.update(s);
  };
  rc.status_every_s = 0.25;
  auto start = std::chrono::steady_clock::now();
  cluster::RunResult result = cluster::coordinate(router, rc, mesh);
  reporter.finish();
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  write_results((dir / job.name).string(), mesh, result.radiosity, result_options(plan.output),
                cluster::run_attributes(rc, cluster::outcome_of(result), mesh, job.scene.empty() ? job.name : job.scene, true));
  write_file_atomic((dir / "ledger.csv").string(), cluster::ledger_csv(result));
  fs::remove(checkpoint);
  return cluster::cluster_summary(result, mesh.size(), seconds);
}

}  // namespace

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

JobPlan plan_job(const std::vector<std::string>& args) {
  CLI::App app{"job"};
  RunFlags run;
  JobPlan plan;
  add_run_flags(&app, run);
  add_output_flags(&app, plan.output);
  std::vector<const char*> argv{"job"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ExtrasError&) {
    std::string extra;  // CLI11's message lists them backwards
    for (const std::string& a : app.remaining()) extra += (extra.empty() ? "" : " ") + a;
    fail("job flags: not run or output flags: {}", extra);
  } catch (const CLI::ParseError& e) {
    fail("job flags: {}", e.what());
  }
  if (!plan.output.out.empty()) fail("job flags: --out: a job's outputs are named by the job");
  if (!plan.output.camera.empty()) camera_flag(plan.output.camera);  // checked now, not when the job runs
  plan.settings = settings_from(run, given_flags(&app));
  if (std::string why = cluster::target_error_problem(plan.settings); !why.empty()) fail("job flags: {}", why);
  return plan;
}

void FarmView::started(uint64_t job) {
  std::lock_guard lock(mutex_);
  job_ = job;
  status_.reset();
  history_.clear();
}

void FarmView::update(const cluster::Status& s) {
  std::lock_guard lock(mutex_);
  status_ = s;
  if (history_.size() >= kMaxPoints) {  // keep every other point: the whole run at half the detail
    std::vector<Point> kept;
    for (std::size_t i = 0; i < history_.size(); i += 2) kept.push_back(history_[i]);
    history_ = std::move(kept);
  }
  history_.push_back({s.elapsed_s, s.error_estimate, s.bundles_done});
}

void FarmView::ended() {
  std::lock_guard lock(mutex_);
  job_ = 0;
}

uint64_t FarmView::job() const {
  std::lock_guard lock(mutex_);
  return job_;
}

std::optional<cluster::Status> FarmView::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

std::vector<FarmView::Point> FarmView::history() const {
  std::lock_guard lock(mutex_);
  return history_;
}

void serve_farm(zmq::socket_t& router, cluster::JobStore& store, const FarmOptions& options, FarmView& view) {
  auto stopping = [&] { return options.stop && options.stop->load(); };
  // A node heard within its liveness is there to take a job.
  const auto alive = std::chrono::milliseconds(static_cast<int64_t>(options.process.heartbeat_ms) * options.process.liveness);
  IdleNodes idle_nodes;
  while (!stopping()) {
    std::erase_if(idle_nodes, [&](const auto& n) { return Clock::now() - n.second > alive; });
    std::optional<cluster::Job> job = store.next();
    if (!job || idle_nodes.empty()) {  // nothing to run, or no node to run it: wait
      idle(router, 200, idle_nodes);
      continue;
    }
    // The idle nodes say HELLO now (asked by an ERROR), so the job's run has them at once.
    for (const auto& [id, heard] : idle_nodes) {
      wire::Error e;
      e.set_reason("a job starts; say HELLO to join it");
      e.set_rejoin(true);
      proto::send(router, {proto::Command::error, e, {}}, &id);
    }
    idle_nodes.clear();
    store.started(job->id, unix_now());
    view.started(job->id);
    say(logging::Level::info, fmt::format("job {} ({}) started", job->id, job->name),
        {{"event", "job started"}, {"job", job->id}, {"name", job->name}, {"runs", job->runs + 1}});
    std::string state = "done", error;
    try {
      std::string summary = run_job(router, *job, store.folder(job->id), options, view);
      write_file_atomic((fs::path(store.folder(job->id)) / "summary.txt").string(), summary);
    } catch (const std::exception& e) {
      if (store.cancel_requested(job->id)) {
        state = "cancelled", error = "cancelled while it ran";
        fs::remove(fs::path(store.folder(job->id)) / "checkpoint");
      } else if (stopping()) {
        view.ended();
        say(logging::Level::info, fmt::format("job {} checkpointed; it resumes when the farm starts again", job->id),
            {{"event", "job stopped"}, {"job", job->id}});
        return;  // stays "running" on disk: queued again at the next start, from its checkpoint
      } else if (options.interrupt && options.interrupt->exchange(false)) {
        // Interrupted for a cancel of the job before it, which had ended meanwhile: this one
        // goes back to the queue and resumes from the checkpoint it just wrote.
        store.requeue(job->id);
        view.ended();
        continue;
      } else {
        state = "failed", error = e.what();
      }
    }
    store.finished(job->id, state, error, unix_now());  // first: a cancel of it now finds it ended
    if (options.interrupt) options.interrupt->store(false);
    view.ended();
    say(state == "failed" ? logging::Level::warn : logging::Level::info,
        fmt::format("job {} ({}) {}{}", job->id, job->name, state, error.empty() ? "" : ": " + error),
        {{"event", "job " + state}, {"job", job->id}, {"error", error}});
  }
}

}  // namespace sirad::cli
