// sirad: the farm coordinator (`sirad-coordinator --serve DIR`; proto/PROTOCOL.md section 10):
// a coordinator that stays up and serves the jobs of its store (cluster/jobs.h) one after
// another on one ROUTER socket, so nodes stay joined between jobs. The highest-priority queued
// job runs next (in submission order within a priority); each job's scene, checkpoint, status,
// outputs, summary and ledger (who ran which bundles) are in its own folder; a job cancelled while it runs stops at its next
// checkpoint; a coordinator stopped or killed mid-job resumes that job from its checkpoint when
// it starts again. Between jobs it answers HELLO with a WELCOME without a run; the next job
// starts once a node is there (heard within its liveness), its idle nodes asked to join it.
#pragma once
#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "cluster/jobs.h"
#include "cluster/settings.h"
#include "cluster/status.h"
#include "cmd/run_flags.h"

namespace sirad::cli {

// What a job's flags ask for: its run's settings and its outputs' (the same flags as
// sirad-coordinator SCENE takes; no others).
struct JobPlan {
  cluster::RunSettings settings;
  OutputFlags output;
};
// Throws sirad::Error (CLI11's message, or the check's) for flags a job cannot take.
JobPlan plan_job(const std::vector<std::string>& args);

// Seconds since the Unix epoch: the times of a job's record (cluster/jobs.h takes them passed in).
double unix_now();

// The running job's latest status and its error over time, for the web page and the API.
class FarmView {
 public:
  struct Point {
    double elapsed_s = 0, error_estimate = -1;
    uint64_t bundles_done = 0;
  };
  void started(uint64_t job);
  void update(const cluster::Status& s);
  void ended();
  // The running job (0: none), its last status and its error history (at most kMaxPoints, thinned).
  uint64_t job() const;
  std::optional<cluster::Status> status() const;
  std::vector<Point> history() const;
  static constexpr std::size_t kMaxPoints = 512;

 private:
  mutable std::mutex mutex_;
  uint64_t job_ = 0;
  std::optional<cluster::Status> status_;
  std::vector<Point> history_;
};

// The largest job a farm takes (patches): its socket's frame bound (96 MiB, as a node's default).
inline constexpr std::size_t kFarmMaxPatches = std::size_t{1} << 22;

struct FarmOptions {
  cluster::ProcessSettings process;           // heartbeat, liveness, checkpoint period (per job)
  const std::atomic<bool>* stop = nullptr;    // set: the running job checkpoints, stays queued; serve returns
  std::atomic<bool>* interrupt = nullptr;     // what a running job watches: set by stop and by a cancel
  bool quiet = true;                          // no live view on the terminal
};

// Serves the store's jobs until *options.stop. `router` is bound (and secured) by the caller.
void serve_farm(zmq::socket_t& router, cluster::JobStore& store, const FarmOptions& options, FarmView& view);

}  // namespace sirad::cli
