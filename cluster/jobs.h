// sirad: the farm's job store (`sirad-coordinator --serve DIR`, proto/PROTOCOL.md section 10):
// the queue of runs a farm coordinator serves one after another, kept on disk so that it
// survives the coordinator's restart. Each job is a folder DIR/jobs/ID holding job.json (its
// record, rewritten atomically on every change), its scene (scene.bin: encoded as nodes receive
// it, scene/encoding.h) unless it names a built-in scene, its checkpoint while it runs, its
// status and its outputs. Plain files and a mutex: no sockets, no clocks (times are passed in).
// Every file read is hostile: a damaged job.json makes its job failed with the reason, never
// a crash or a job run twice.
#pragma once
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cluster/settings.h"

namespace sirad::cluster {

// What a job runs, as its flags asked when it was submitted (farm/farm.h plan_job): the run's
// settings, kept as the table writes them (settings_text), so a job reads back the same run
// whatever becomes of the flags; its output flags as a checkpoint keeps them (cli
// output_args); the nodes it waits for and takes.
struct JobRun {
  RunSettings settings;
  std::vector<std::string> output;
  uint32_t min_nodes = 1;  // nodes ready before its first grant
  uint32_t max_nodes = 0;  // the most nodes it takes (0: every node there is)
};

struct Job {
  uint64_t id = 0;                 // 1, 2, ... in submission order
  std::string name;                // the outputs' base name (NAME.exr, ...)
  std::string scene;               // a built-in scene's name, or "" for the job's scene.bin
  std::vector<std::string> args;   // its flags as submitted (what the page shows)
  // What it runs; none only in a job file of an earlier version, whose run is planned from its
  // args when it comes to run.
  std::optional<JobRun> run;
  int priority = 0;                // higher runs first; equal: in submission order
  std::string state = "queued";    // queued | running | done | failed | cancelled
  double submitted = 0, started = 0, finished = 0;  // Unix seconds (0: not yet)
  std::string error;               // failed: why; cancelled: by whom
  uint32_t runs = 0;               // times it was started (a restart resumes it: 2 or more)
  // Runs in a row that the farm died in: left `running` on disk, which only a farm that stopped
  // without ending them leaves (a stop checkpoints a job and queues it; an end records it).
  uint32_t lost_runs = 0;
};

// After this many lost runs in a row a farm's restart fails the job instead of resuming it: a
// job whose input crashes the farm's process (through code the farm runs for it: the scene's
// import and checks, its preview, the coordinator's checks of tiles) would otherwise take the
// farm down again at every start. One loss is resumed, since a farm also dies of causes that
// are no job's (a power cut, kill -9).
inline constexpr uint32_t kMaxLostRuns = 2;

// The bounds a job must keep (what a submission or a job file may claim).
inline constexpr std::size_t kMaxJobs = 100000;
inline constexpr std::size_t kMaxJobArgs = 64, kMaxJobArgBytes = 4096, kMaxJobNameBytes = 64;
inline constexpr std::size_t kMaxJobFileBytes = 1 << 20;
inline constexpr int kMaxPriority = 1000000;
inline constexpr uint32_t kMaxJobNodes = 4096;  // --min-nodes, --max-nodes

// The job's record as JSON (job.json) and back; from_json throws sirad::Error naming `origin`
// and the field for anything out of bounds.
std::string job_json(const Job& job);
Job job_from_json(const std::string& text, const std::string& origin);

// Throws sirad::Error for a name that is not 1..64 of [A-Za-z0-9._-] (it names files), not
// starting with a dot, or that is "preview" (NAME.png and NAME.glb would be the farm's previews
// of the job).
void check_job_name(const std::string& name);

class JobStore {
 public:
  // Opens (making it) DIR and DIR/jobs and reads every job there. A job left `running` (the
  // farm died while it ran) counts a lost run and is queued again to resume from its checkpoint,
  // or is failed with the reason at its kMaxLostRuns-th loss in a row (`now`: that time). With
  // `recover` false (a look at the store, which a running farm may own) nothing is changed.
  JobStore(std::string dir, double now, bool recover = true);

  // A new queued job (its folder, scene.bin when `scene_bytes` is given, job.json). Throws
  // sirad::Error for a bad name, too many args or output flags, or too many jobs.
  Job submit(const std::string& name, const std::string& scene, const std::string& scene_bytes, std::vector<std::string> args,
             JobRun run, int priority, double now);
  std::vector<Job> list() const;
  std::optional<Job> get(uint64_t id) const;
  // The next job to run: queued, highest priority, oldest.
  std::optional<Job> next() const;

  // State changes, each written to job.json before it returns.
  void started(uint64_t id, double now);
  void finished(uint64_t id, const std::string& state, const std::string& error, double now);
  // A running job the farm stopped at its checkpoint (the farm itself stopping): queued again,
  // its lost runs forgiven.
  void stopped(uint64_t id);
  // A queued job is cancelled at once; a running one is marked (cancel_requested) for the
  // farm to stop. False: no such job, or it has ended.
  bool cancel(uint64_t id, double now);
  bool cancel_requested(uint64_t id) const;

  const std::string& dir() const { return dir_; }
  std::string folder(uint64_t id) const;

 private:
  void write(const Job& job) const;  // job.json, atomically; caller holds mutex_
  Job* find(uint64_t id);

  std::string dir_;
  mutable std::mutex mutex_;
  std::vector<Job> jobs_;  // by id
  std::vector<uint64_t> cancel_requested_;
  uint64_t next_id_ = 1;
};

}  // namespace sirad::cluster
