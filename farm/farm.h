// sirad: the farm coordinator (`sirad-coordinator --serve DIR`; proto/PROTOCOL.md section 11):
// a coordinator that stays up and serves the jobs of its store (cluster/jobs.h) on one ROUTER
// socket, so nodes stay joined between jobs. It is a broker: each running job is an ordinary
// run (coordinator/coordinator.h) on a thread of its own, on an inproc ROUTER socket of its
// own; the farm's socket hands each node's messages to the job the node is in, and the job's
// answers back. A node that says HELLO joins the running job of the highest priority that has
// room for it (a job's --max-nodes); a queued job starts when a node is free, so jobs that
// cannot use every node share the farm. Each job's scene, checkpoint, status, preview, outputs,
// summary and ledger (who ran which bundles) are in its own folder; a job cancelled while it
// runs stops at once (checkpoint, then its nodes move on); a farm stopped or killed mid-job
// resumes that job from its checkpoint when it starts again. A free node's HELLO is answered
// with a WELCOME without a run.
#pragma once
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "cli/run_flags.h"
#include "cluster/jobs.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "proto/peer_bytes.h"

namespace sirad::cli {

// What a job's flags ask for: its run's settings and its outputs' (the same flags as
// sirad-coordinator SCENE takes; no others).
struct JobPlan {
  cluster::RunSettings settings;
  OutputFlags output;
  uint32_t min_nodes = 1;  // --min-nodes: nodes ready before its first grant
  uint32_t max_nodes = 0;  // --max-nodes: the most nodes it takes (0: every node there is)
};
// Throws sirad::Error (CLI11's message, or the check's) for flags a job cannot take, among
// them a meshing target beyond kFarmMaxPatches.
JobPlan plan_job(const std::vector<std::string>& args);
// The plan as a job file keeps it, and back (the output flags parsed again: a job file edited
// since throws sirad::Error naming `origin`). A job of an earlier version, without its run,
// is planned from its args.
cluster::JobRun job_run(const JobPlan& plan);
JobPlan plan_of(const cluster::Job& job, const std::string& origin);

// Seconds since the Unix epoch: the times of a job's record (cluster/jobs.h takes them passed in).
double unix_now();

// The running jobs' latest status and their error over time, for the web page and the API.
class FarmView {
 public:
  struct Point {
    double elapsed_s = 0, error_estimate = -1;
    uint64_t bundles_done = 0;
  };
  void started(uint64_t job);
  void update(uint64_t job, const cluster::Status& s);
  void ended(uint64_t job);
  // The running jobs (by id); a running job's last status and its error history (at most
  // kMaxPoints, thinned); nothing for a job that is not running.
  std::vector<uint64_t> running() const;
  std::optional<cluster::Status> status(uint64_t job) const;
  std::vector<Point> history(uint64_t job) const;
  static constexpr std::size_t kMaxPoints = 512;

 private:
  struct Running {
    std::optional<cluster::Status> status;
    std::vector<Point> history;
  };
  mutable std::mutex mutex_;
  std::map<uint64_t, Running> jobs_;
};

// The largest job a farm takes (patches): its socket's frame bound (96 MiB, as a node's default).
inline constexpr std::size_t kFarmMaxPatches = std::size_t{1} << 22;

// The most nodes a farm knows at once (busy and free): a node beyond it is refused until one
// is forgotten (silent for its liveness).
inline constexpr std::size_t kFarmMaxNodes = 4096;

struct FarmOptions {
  cluster::ProcessSettings process;           // heartbeat, liveness, checkpoint period (per job)
  const std::atomic<bool>* stop = nullptr;    // set: the running jobs checkpoint and stay queued; serve returns
  proto::PeerBytes* peer_bytes = nullptr;     // the farm socket's bytes per peer (told what it reads)
};

// Serves the store's jobs until *options.stop. `router` is bound (and secured) by the caller,
// on `context` (the jobs' inproc sockets are made on it).
void serve_farm(zmq::context_t& context, zmq::socket_t& router, cluster::JobStore& store, const FarmOptions& options,
                FarmView& view);

}  // namespace sirad::cli
