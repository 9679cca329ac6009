// sirad: the farm's job store (see jobs.h).
#include "cluster/jobs.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad::cluster {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kStates = {"queued", "running", "done", "failed", "cancelled"};

template <typename T>
T field(const nlohmann::json& j, const char* key, const std::string& origin) {
  if (!j.contains(key)) fail("{}: no '{}'", origin, key);
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    fail("{}: '{}' is not of the right kind", origin, key);
  }
}

double time_field(const nlohmann::json& j, const char* key, const std::string& origin) {
  double t = field<double>(j, key, origin);
  if (!std::isfinite(t) || t < 0 || t > 1e11) fail("{}: '{}' is not a time", origin, key);
  return t;
}

// A list of strings, each of at most kMaxJobArgBytes, at most kMaxJobArgs of them (`what`: how
// the error names it).
void check_strings(const std::vector<std::string>& list, const std::string& what) {
  if (list.size() > kMaxJobArgs) fail("{} {} (at most {})", list.size(), what, kMaxJobArgs);
  for (const std::string& a : list)
    if (a.size() > kMaxJobArgBytes) fail("one of its {} has {} bytes (at most {})", what, a.size(), kMaxJobArgBytes);
}

void check_run(const JobRun& r) {
  check_strings(r.output, "output flags");
  if (r.min_nodes < 1 || r.min_nodes > kMaxJobNodes || r.max_nodes > kMaxJobNodes)
    fail("nodes {}..{}: outside 1..{}", r.min_nodes, r.max_nodes, kMaxJobNodes);
  if (r.max_nodes != 0 && r.min_nodes > r.max_nodes) fail("min_nodes {} is more than max_nodes {}", r.min_nodes, r.max_nodes);
  check(r.settings);
}

nlohmann::ordered_json run_json(const JobRun& r) {
  nlohmann::ordered_json settings = nlohmann::ordered_json::object();
  for (const auto& [flag, text] : settings_text(r.settings)) settings[flag] = text;
  return {{"settings", std::move(settings)}, {"output", r.output}, {"min_nodes", r.min_nodes}, {"max_nodes", r.max_nodes}};
}

JobRun run_from_json(const nlohmann::json& j, const std::string& origin) {
  if (!j.is_object()) fail("{}: 'run' is not an object", origin);
  const std::string where = origin + ": run";
  const nlohmann::json settings = field<nlohmann::json>(j, "settings", where);
  if (!settings.is_object() || settings.size() > setting_rows().size())
    fail("{}: 'settings' is not an object of at most {} settings", where, setting_rows().size());
  SettingsText text;
  for (const auto& [flag, value] : settings.items()) {
    if (!value.is_string()) fail("{}: setting '{}' is not a string", where, flag.substr(0, 40));
    text.emplace_back(flag, value.get<std::string>());
  }
  JobRun r;
  r.settings = settings_from_text(text, where);
  r.output = field<std::vector<std::string>>(j, "output", where);
  r.min_nodes = field<uint32_t>(j, "min_nodes", where);
  r.max_nodes = field<uint32_t>(j, "max_nodes", where);
  try {
    check_run(r);
  } catch (const Error& e) {
    fail("{}: {}", where, e.what());
  }
  return r;
}

}  // namespace

void check_job_name(const std::string& name) {
  if (name.empty() || name.size() > kMaxJobNameBytes || name[0] == '.' ||
      !std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
      }))
    fail("job name '{}': 1 to {} of A-Z a-z 0-9 . _ -, not starting with a dot", name.substr(0, 80), kMaxJobNameBytes);
  if (name == "preview") fail("job name 'preview': its PNG and glb would be the farm's preview.png and preview.glb of the job; choose another");
}

std::string job_json(const Job& j) {
  nlohmann::ordered_json o = {{"id", j.id},           {"name", j.name},         {"scene", j.scene},         {"args", j.args},
                              {"priority", j.priority}, {"state", j.state},     {"submitted", j.submitted}, {"started", j.started},
                              {"finished", j.finished}, {"error", j.error},     {"runs", j.runs},
                              {"lost_runs", j.lost_runs}};
  if (j.run) o["run"] = run_json(*j.run);
  return o.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

Job job_from_json(const std::string& text, const std::string& origin) {
  nlohmann::json j;
  try {
    j = parse_json_bounded(text, origin, kMaxJobFileBytes);
  } catch (const nlohmann::json::parse_error& e) {
    fail("{}: not JSON: {}", origin, e.what());
  }
  if (!j.is_object()) fail("{}: not a JSON object", origin);
  Job job;
  job.id = field<uint64_t>(j, "id", origin);
  if (job.id == 0 || job.id > kMaxJobs * 100) fail("{}: 'id' {} is out of range", origin, job.id);
  job.name = field<std::string>(j, "name", origin);
  try {
    check_job_name(job.name);
  } catch (const Error& e) {
    fail("{}: {}", origin, e.what());
  }
  job.scene = field<std::string>(j, "scene", origin);
  if (job.scene.size() > kMaxJobArgBytes) fail("{}: 'scene' is too long", origin);
  job.args = field<std::vector<std::string>>(j, "args", origin);
  try {
    check_strings(job.args, "args");
  } catch (const Error& e) {
    fail("{}: {}", origin, e.what());
  }
  if (j.contains("run")) job.run = run_from_json(j.at("run"), origin);  // absent in older stores
  job.priority = field<int>(j, "priority", origin);
  if (std::abs(job.priority) > kMaxPriority) fail("{}: 'priority' {} is out of range", origin, job.priority);
  job.state = field<std::string>(j, "state", origin);
  if (std::find(kStates.begin(), kStates.end(), job.state) == kStates.end()) fail("{}: 'state' '{}' is unknown", origin, job.state.substr(0, 40));
  job.submitted = time_field(j, "submitted", origin);
  job.started = time_field(j, "started", origin);
  job.finished = time_field(j, "finished", origin);
  job.error = field<std::string>(j, "error", origin);
  if (job.error.size() > kMaxJobFileBytes / 4) job.error.resize(kMaxJobFileBytes / 4);
  job.runs = field<uint32_t>(j, "runs", origin);
  if (j.contains("lost_runs")) job.lost_runs = field<uint32_t>(j, "lost_runs", origin);  // absent in older stores
  return job;
}

JobStore::JobStore(std::string dir, double now, bool recover) : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(fs::path(dir_) / "jobs", ec);
  if (ec) fail("{}: cannot make the farm's folder: {}", dir_, ec.message());
  std::vector<uint64_t> ids;
  for (const auto& e : fs::directory_iterator(fs::path(dir_) / "jobs", ec)) {
    const std::string name = e.path().filename().string();
    const bool digits = std::all_of(name.begin(), name.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (!e.is_directory() || name.empty() || name.size() > 12 || !digits) continue;
    ids.push_back(std::stoull(name));
    if (ids.size() > kMaxJobs) fail("{}: more than {} jobs", dir_, kMaxJobs);
  }
  if (ec) fail("{}: cannot read the farm's jobs: {}", dir_, ec.message());
  std::sort(ids.begin(), ids.end());
  for (uint64_t id : ids) {
    next_id_ = std::max(next_id_, id + 1);
    const std::string path = (fs::path(folder(id)) / "job.json").string();
    Job job;
    try {
      job = job_from_json(read_file_whole(path, "job", kMaxJobFileBytes), path);
      if (job.id != id) fail("{}: 'id' {} is not its folder's", path, job.id);
      if (recover && job.state == "running") {  // the farm died while it ran
        if (++job.lost_runs >= kMaxLostRuns) {
          job.state = "failed";
          job.error = fmt::format("the farm stopped {} times in a row while this job ran (its input may crash the farm); "
                                  "submit it again to retry",
                                  job.lost_runs);
          job.finished = now;
        } else {
          job.state = "queued";  // it resumes from its checkpoint
        }
        write(job);
      }
    } catch (const Error& e) {  // shown as failed; the damaged file stays as it is
      job = Job{};
      job.id = id;
      job.name = fmt::format("job-{}", id);
      job.state = "failed";
      job.error = e.what();
    }
    jobs_.push_back(std::move(job));
  }
}

std::string JobStore::folder(uint64_t id) const { return (fs::path(dir_) / "jobs" / std::to_string(id)).string(); }

void JobStore::write(const Job& job) const {
  write_file_atomic((fs::path(folder(job.id)) / "job.json").string(), job_json(job));
}

Job* JobStore::find(uint64_t id) {
  auto it = std::find_if(jobs_.begin(), jobs_.end(), [&](const Job& j) { return j.id == id; });
  return it == jobs_.end() ? nullptr : &*it;
}

Job JobStore::submit(const std::string& name, const std::string& scene, const std::string& scene_bytes,
                     std::vector<std::string> args, JobRun run, int priority, double now) {
  check_job_name(name);
  if (scene.empty() == scene_bytes.empty()) fail("a job needs a built-in scene's name or a scene's bytes, not both");
  if (scene.size() > kMaxJobArgBytes) fail("scene name of {} bytes", scene.size());
  check_strings(args, "args");
  check_run(run);
  if (std::abs(priority) > kMaxPriority) fail("priority {} is out of range (+-{})", priority, kMaxPriority);
  std::lock_guard lock(mutex_);
  if (jobs_.size() >= kMaxJobs) fail("the farm holds {} jobs already (at most {})", jobs_.size(), kMaxJobs);
  Job job;
  job.id = next_id_++;
  job.name = name;
  job.scene = scene;
  job.args = std::move(args);
  job.run = std::move(run);
  job.priority = priority;
  job.submitted = now;
  std::error_code ec;
  fs::create_directories(folder(job.id), ec);
  if (ec) fail("{}: cannot make the job's folder: {}", folder(job.id), ec.message());
  if (!scene_bytes.empty()) write_file_atomic((fs::path(folder(job.id)) / "scene.bin").string(), scene_bytes);
  write(job);  // last: a folder without job.json is no job
  jobs_.push_back(job);
  return job;
}

std::vector<Job> JobStore::list() const {
  std::lock_guard lock(mutex_);
  return jobs_;
}

std::optional<Job> JobStore::get(uint64_t id) const {
  std::lock_guard lock(mutex_);
  for (const Job& j : jobs_)
    if (j.id == id) return j;
  return std::nullopt;
}

std::optional<Job> JobStore::next() const {
  std::lock_guard lock(mutex_);
  const Job* best = nullptr;
  for (const Job& j : jobs_)
    if (j.state == "queued" && (!best || j.priority > best->priority)) best = &j;  // ids ascend: the oldest of a priority wins
  return best ? std::optional<Job>(*best) : std::nullopt;
}

void JobStore::started(uint64_t id, double now) {
  std::lock_guard lock(mutex_);
  Job* j = find(id);
  if (!j) fail("no job {}", id);
  j->state = "running";
  if (j->started == 0) j->started = now;
  ++j->runs;
  write(*j);
}

void JobStore::finished(uint64_t id, const std::string& state, const std::string& error, double now) {
  std::lock_guard lock(mutex_);
  Job* j = find(id);
  if (!j) fail("no job {}", id);
  j->state = state;
  j->error = error;
  j->finished = now;
  j->lost_runs = 0;
  std::erase(cancel_requested_, id);
  write(*j);
}

void JobStore::stopped(uint64_t id) {
  std::lock_guard lock(mutex_);
  Job* j = find(id);
  if (!j) fail("no job {}", id);
  if (j->state != "running") return;
  j->state = "queued";
  j->lost_runs = 0;
  write(*j);
}

bool JobStore::cancel(uint64_t id, double now) {
  std::lock_guard lock(mutex_);
  Job* j = find(id);
  if (!j) return false;
  if (j->state == "queued") {
    j->state = "cancelled";
    j->error = "cancelled before it ran";
    j->finished = now;
    write(*j);
    return true;
  }
  if (j->state != "running") return false;
  if (std::find(cancel_requested_.begin(), cancel_requested_.end(), id) == cancel_requested_.end()) cancel_requested_.push_back(id);
  return true;
}

bool JobStore::cancel_requested(uint64_t id) const {
  std::lock_guard lock(mutex_);
  return std::find(cancel_requested_.begin(), cancel_requested_.end(), id) != cancel_requested_.end();
}

}  // namespace sirad::cluster
