// sirad tests: the farm's job store (cluster/jobs.h): order by priority then submission, state
// changes that survive a reload, a job left running queued again, hostile job files.
#include <filesystem>
#include <fstream>
#include <tuple>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "cluster/jobs.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad::cluster {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path = fs::temp_directory_path() / fmt::format("sirad_jobs_{}_{}", ::getpid(), counter++);
  TempDir() { fs::remove_all(path); }
  ~TempDir() { fs::remove_all(path); }
  static inline int counter = 0;
};

TEST(JobStore, RunsTheHighestPriorityFirstThenTheOldest) {
  TempDir d;
  JobStore store(d.path.string(), 0);
  EXPECT_FALSE(store.next());
  const Job a = store.submit("a", "cornell", "", {"--bundles", "10"}, JobRun{}, 0, 100);
  const Job b = store.submit("b", "cornell", "", {}, JobRun{}, 5, 101);
  const Job c = store.submit("c", "furnace", "", {}, JobRun{}, 5, 102);
  EXPECT_EQ(a.id, 1u);
  EXPECT_EQ(store.next()->id, b.id);  // priority 5, submitted before c
  store.started(b.id, 110);
  EXPECT_EQ(store.next()->id, c.id);
  {
    JobStore again(d.path.string(), 0);  // the farm restarted with b running: back in the queue, first again
    EXPECT_EQ(again.get(b.id)->state, "queued");
    EXPECT_EQ(again.next()->id, b.id);
  }
  JobStore s2(d.path.string(), 0);  // the restarted farm's store
  s2.started(b.id, 111);
  EXPECT_EQ(s2.get(b.id)->runs, 2u);
  EXPECT_EQ(s2.get(b.id)->started, 110);  // the first start is kept
  s2.finished(b.id, "done", "", 120);
  s2.started(c.id, 121);
  s2.finished(c.id, "failed", "no nodes", 130);
  EXPECT_EQ(s2.next()->id, a.id);
  EXPECT_TRUE(s2.cancel(a.id, 131));  // queued: cancelled at once
  EXPECT_EQ(s2.get(a.id)->state, "cancelled");
  EXPECT_FALSE(s2.next());
  EXPECT_FALSE(s2.cancel(a.id, 132));  // ended
  EXPECT_FALSE(s2.cancel(99, 132));    // no such job
}

// A job left running on disk is one the farm died in. The first loss resumes it; the second
// in a row fails it with the reason, so a job whose input crashes the farm's process cannot
// take the farm down at every start. A run that ends, or that the farm stops at its
// checkpoint, forgives the losses.
TEST(JobStore, AJobTheFarmDiesInTwiceInARowIsFailedNotResumed) {
  TempDir d;
  {
    JobStore store(d.path.string(), 0);
    store.submit("poison", "cornell", "", {}, JobRun{}, 0, 1);
    store.submit("fine", "cornell", "", {}, JobRun{}, 0, 2);
    store.started(1, 3);
  }  // the farm dies with job 1 running
  for (int look = 0; look < 3; ++look) {  // looks at the store (--check-config) change nothing
    JobStore seen(d.path.string(), 5, false);
    EXPECT_EQ(seen.get(1)->state, "running");
    EXPECT_EQ(seen.get(1)->lost_runs, 0u);
  }
  {
    JobStore again(d.path.string(), 10);
    EXPECT_EQ(again.get(1)->state, "queued");
    EXPECT_EQ(again.get(1)->lost_runs, 1u);
    again.started(1, 11);
  }  // and dies again in it
  {
    JobStore third(d.path.string(), 20);
    const Job j = *third.get(1);
    EXPECT_EQ(j.state, "failed");
    EXPECT_EQ(j.finished, 20);
    EXPECT_NE(j.error.find("stopped 2 times in a row"), std::string::npos) << j.error;
    EXPECT_EQ(third.next()->id, 2u);  // the farm goes on with the others
    third.started(2, 21);
    third.stopped(2);  // the farm stops, checkpointing job 2: not a loss
  }
  {
    JobStore fourth(d.path.string(), 30);
    EXPECT_EQ(fourth.get(2)->state, "queued");
    EXPECT_EQ(fourth.get(2)->lost_runs, 0u);
    fourth.started(2, 31);
  }  // one loss
  {
    JobStore fifth(d.path.string(), 40);
    EXPECT_EQ(fifth.get(2)->lost_runs, 1u);
    fifth.started(2, 41);
    fifth.stopped(2);  // then a clean stop: forgiven
  }
  JobStore sixth(d.path.string(), 50);
  EXPECT_EQ(sixth.get(2)->state, "queued");
  EXPECT_EQ(sixth.get(2)->lost_runs, 0u);
  EXPECT_EQ(sixth.get(1)->state, "failed");  // stays failed
}

// Every change is on disk: a new store of the same folder sees the same jobs, a job that was
// running is queued again (its process stopped mid-run; it resumes from its checkpoint), and
// new ids continue after the highest.
TEST(JobStore, SurvivesARestartAndQueuesTheJobThatWasRunning) {
  TempDir d;
  {
    JobStore store(d.path.string(), 0);
    store.submit("done-one", "cornell", "", {}, JobRun{}, 0, 1);
    store.submit("uploaded", "", std::string("SCENEBYTES"), {"--patches", "300"}, JobRun{}, 2, 2);
    store.started(1, 3);
    store.finished(1, "done", "", 4);
    store.started(2, 5);
  }
  JobStore again(d.path.string(), 0);
  ASSERT_EQ(again.list().size(), 2u);
  EXPECT_EQ(again.get(1)->state, "done");
  EXPECT_EQ(again.get(1)->finished, 4);
  const Job j = *again.get(2);
  EXPECT_EQ(j.state, "queued");
  EXPECT_EQ(j.runs, 1u);
  EXPECT_EQ(j.args, (std::vector<std::string>{"--patches", "300"}));
  EXPECT_TRUE(fs::exists(d.path / "jobs" / "2" / "scene.bin"));
  EXPECT_EQ(again.next()->id, 2u);
  EXPECT_EQ(again.submit("third", "cornell", "", {}, JobRun{}, 0, 6).id, 3u);
  // Cancelling a running job is only marked: the farm stops it and records the end.
  again.started(2, 7);
  EXPECT_TRUE(again.cancel(2, 8));
  EXPECT_TRUE(again.cancel_requested(2));
  EXPECT_EQ(again.get(2)->state, "running");
  again.finished(2, "cancelled", "cancelled while it ran", 9);
  EXPECT_FALSE(again.cancel_requested(2));
}

// A job file that is not what the store writes (damaged, hand-edited, hostile) makes its job
// failed with the reason, and is left as it is; the other jobs load. Bad submissions are one
// clear error each.
TEST(JobStore, HostileJobFilesAndSubmissionsAreRefused) {
  TempDir d;
  {
    JobStore store(d.path.string(), 0);
    for (int i = 0; i < 5; ++i) store.submit(fmt::format("j{}", i), "cornell", "", {}, JobRun{}, 0, i);
  }
  const std::vector<std::string> bad = {"{not json", "[1, 2]", R"({"id": 2})",
                                        R"({"id": 3, "name": "../../etc", "scene": "", "args": [], "priority": 0, "state": "queued", "submitted": 0, "started": 0, "finished": 0, "error": "", "runs": 0})",
                                        R"({"id": 4, "name": "x", "scene": "", "args": [], "priority": 0, "state": "exploded", "submitted": 0, "started": 0, "finished": 0, "error": "", "runs": 0})"};
  for (std::size_t i = 0; i < bad.size(); ++i) std::ofstream(d.path / "jobs" / std::to_string(i + 1) / "job.json") << bad[i];
  JobStore store(d.path.string(), 0);
  ASSERT_EQ(store.list().size(), 5u);
  for (uint64_t id = 1; id <= 5; ++id) {
    EXPECT_EQ(store.get(id)->state, "failed") << id;
    EXPECT_NE(store.get(id)->error.find("job.json"), std::string::npos) << store.get(id)->error;
  }
  EXPECT_EQ(std::ifstream(d.path / "jobs" / "1" / "job.json").get(), '{');  // left as it was
  EXPECT_FALSE(store.next());
  EXPECT_THROW(store.submit("../x", "cornell", "", {}, JobRun{}, 0, 1), Error);
  EXPECT_THROW(store.submit(".hidden", "cornell", "", {}, JobRun{}, 0, 1), Error);
  EXPECT_THROW(store.submit("preview", "cornell", "", {}, JobRun{}, 0, 1), Error);  // preview.png is the farm's
  EXPECT_THROW(store.submit("ok", "", "", {}, JobRun{}, 0, 1), Error);             // no scene
  EXPECT_THROW(store.submit("ok", "cornell", "x", {}, JobRun{}, 0, 1), Error);     // both
  EXPECT_THROW(store.submit("ok", "cornell", "", std::vector<std::string>(kMaxJobArgs + 1, "-q"), JobRun{}, 0, 1), Error);
  EXPECT_THROW(store.submit("ok", "cornell", "", {}, JobRun{}, kMaxPriority + 1, 1), Error);
}

// A job keeps the run it was planned to, not its flags: the settings as the table writes them
// (every one spelled out), its output flags and nodes, read back to the same settings after a
// restart. A job file of an earlier version (args only) loads without a run, to be planned from
// its args; a run that no job can have fails its job with the field named.
TEST(JobStore, AJobKeepsTheRunItWasPlannedTo) {
  TempDir d;
  JobRun run;
  run.settings.mesh_options.target_patches = 300;
  run.settings.bundles = 64;
  run.settings.seed = 9;
  run.settings.mode = Mode::sync;
  run.settings.balance = false;
  run.settings.shots_per_bundle = 0.125;
  run.output = {"--width", "48", "--height", "32"};
  run.min_nodes = 2;
  run.max_nodes = 3;
  {
    JobStore store(d.path.string(), 0);
    store.submit("planned", "cornell", "", {"--patches", "300"}, run, 0, 1);
    store.submit("old", "cornell", "", {"--bundles", "5"}, run, 0, 2);
  }
  const std::string planned = read_file_whole((d.path / "jobs" / "1" / "job.json").string(), "job", kMaxJobFileBytes);
  EXPECT_NE(planned.find(R"("settings": {
      "patches": "300",)"), std::string::npos) << planned;
  EXPECT_NE(planned.find(R"("shots-per-bundle": "0.125")"), std::string::npos) << planned;
  std::ofstream(d.path / "jobs" / "2" / "job.json")
      << R"({"id": 2, "name": "old", "scene": "cornell", "args": ["--bundles", "5"], "priority": 0, "state": "queued", )"
      << R"("submitted": 2, "started": 0, "finished": 0, "error": "", "runs": 0})";
  const std::vector<std::tuple<int, std::string, std::string>> bad_runs = {
           {3, R"("run": {"settings": {"bundles": "0"}, "output": [], "min_nodes": 1, "max_nodes": 0})", "run: bundles: must be in [1, "},
           {4, R"("run": {"settings": {"nodes": "2"}, "output": [], "min_nodes": 1, "max_nodes": 0})", "run: 'nodes' is not a run setting"},
           {5, R"("run": {"settings": {"seed": 7}, "output": [], "min_nodes": 1, "max_nodes": 0})", "run: setting 'seed' is not a string"},
           {6, R"("run": {"settings": {}, "output": [], "min_nodes": 3, "max_nodes": 2})", "run: min_nodes 3 is more than max_nodes 2"},
           {7, R"("run": {"settings": {}, "output": [], "min_nodes": -1, "max_nodes": 0})", "run: nodes 4294967295..0: outside 1..4096"},
           {8, R"("run": {"output": [], "min_nodes": 1, "max_nodes": 0})", "run: no 'settings'"}};
  for (const auto& [id, bad, expect] : bad_runs) {
    fs::create_directories(d.path / "jobs" / std::to_string(id));
    std::ofstream(d.path / "jobs" / std::to_string(id) / "job.json")
        << fmt::format(R"({{"id": {}, "name": "bad", "scene": "cornell", "args": [], "priority": 0, "state": "queued", )", id)
        << R"("submitted": 2, "started": 0, "finished": 0, "error": "", "runs": 0, )" << bad << "}";
  }
  JobStore store(d.path.string(), 0);
  const Job j = *store.get(1);
  ASSERT_TRUE(j.run);
  EXPECT_EQ(j.run->output, run.output);
  EXPECT_EQ(j.run->min_nodes, 2u);
  EXPECT_EQ(j.run->max_nodes, 3u);
  EXPECT_EQ(settings_text(j.run->settings), settings_text(run.settings));
  EXPECT_EQ(j.run->settings.shots_per_bundle, 0.125);
  EXPECT_EQ(store.get(2)->state, "queued");
  EXPECT_FALSE(store.get(2)->run);
  for (const auto& [id, bad, expect] : bad_runs) {
    EXPECT_EQ(store.get(id)->state, "failed") << id;
    EXPECT_NE(store.get(id)->error.find("job.json: " + expect), std::string::npos) << store.get(id)->error;
  }
}

// A job file nested deeper than kMaxJsonDepth (here 200,000 levels in its args) fails its job by
// its depth, found before the file is parsed.
TEST(JobStore, AJobFileNestedTooDeepFailsItsJob) {
  TempDir d;
  JobStore(d.path.string(), 0).submit("deep", "cornell", "", {}, JobRun{}, 0, 1);
  std::ofstream(d.path / "jobs" / "1" / "job.json") << R"({"id": 1, "args": )" << std::string(200000, '[') << std::string(200000, ']')
                                                    << "}";
  JobStore store(d.path.string(), 0);
  EXPECT_EQ(store.get(1)->state, "failed");
  EXPECT_NE(store.get(1)->error.find(fmt::format("job.json: JSON nested deeper than {} levels", kMaxJsonDepth)), std::string::npos)
      << store.get(1)->error;
}

}  // namespace
}  // namespace sirad::cluster
