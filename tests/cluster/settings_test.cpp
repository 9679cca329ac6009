// sirad tests: the table of a run's settings (cluster/settings.h setting_rows): every row is a
// flag that parses its default and a sample of its own, and every value a flag sets reaches a
// node (the wire's Run) or a resumed coordinator (the checkpoint) unchanged; what no run can
// have is refused by check(), whoever gives it.
#include <algorithm>
#include <map>
#include <set>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "cli/run_flags.h"
#include "cluster/settings.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

// A value of each flag other than its default. A row added without one here fails the first
// test: each setting is shown to survive the wire or the checkpoint.
const std::map<std::string, std::string> kSamples = {
    {"patches", "5000"},        {"max-edge", "0.25"},      {"bundles", "777"},         {"grid", "96"},
    {"seed", "18446744073709551615"}, {"rule", "average"},   {"directions", "random"},   {"control-variate", "off"},
    {"burn-in", "12"},          {"shots-per-bundle", "1.5"}, {"shot-resolution", "64"}, {"exchange-every", "24"},
    {"exchange-fraction", "0.375"}, {"topology", "ring"},  {"mode", "sync"},           {"balance", "off"},
    {"time-limit", "12.5"},     {"target-error", "0.0625"}, {"chunks", "7"},             {"max-patches", "1000000"},
};

// The settings of `given` flags (each flag's text) as the command lines make them.
RunSettings from_flags(const std::map<std::string, std::string>& given) {
  cli::RunFlags flags;
  std::set<std::string> names;
  for (const auto& [flag, text] : given) {
    flags.text[flag] = text;
    names.insert("--" + flag);
  }
  return cli::settings_from(flags, names);
}

// `s` through everything that carries a run: the wire's Run (WELCOME) and the checkpoint.
RunSettings carried(const RunSettings& s, const PatchMesh& mesh) {
  std::vector<uint32_t> starts;
  for (uint32_t c = 0; c < s.chunks; ++c) starts.push_back(c);
  starts.push_back(static_cast<uint32_t>(mesh.size()));
  const wire::Run run = to_wire(s, mesh, starts);
  wire::Checkpoint c;
  put_settings(c, s, run);
  return settings_of(c);
}

TEST(SettingsTable, EveryFlagParsesAndItsValueReachesTheNodesAndTheCheckpoint) {
  const PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 200});
  std::set<std::string> flags;
  for (const SettingRow& row : setting_rows()) {
    const std::string flag(row.flag);
    SCOPED_TRACE(flag);
    EXPECT_TRUE(flags.insert(flag).second) << "two rows of one flag";
    ASSERT_TRUE(row.parse && row.text && !row.help.empty() && !row.type.empty()) << "every row parses and writes its text";
    ASSERT_TRUE(kSamples.count(flag)) << "no sample for a new row";
    EXPECT_TRUE(row.to_run || row.to_checkpoint || flag == "chunks") << "reaches neither the nodes nor the checkpoint";
    EXPECT_EQ(row.to_run != nullptr || flag == "chunks", row.from_run != nullptr);  // chunks: as their starts
    EXPECT_EQ(row.to_checkpoint != nullptr, row.from_checkpoint != nullptr);
    if (!row.default_text.empty()) {
      RunSettings s;
      EXPECT_NO_THROW(row.parse(s, std::string(row.default_text)));
    }
    // The sample alone, on the command lines' defaults: it changes the settings, and the
    // wire and the checkpoint carry it (compared as the wire writes it: every field of the Run
    // and the coordinator's three).
    const RunSettings defaults = from_flags({});
    const RunSettings s = from_flags({{flag, kSamples.at(flag)}});
    const RunSettings back = carried(s, mesh);
    std::vector<uint32_t> starts;
    for (uint32_t c = 0; c < s.chunks; ++c) starts.push_back(c);
    starts.push_back(static_cast<uint32_t>(mesh.size()));
    wire::Checkpoint sent, returned, plain;
    put_settings(sent, s, to_wire(s, mesh, starts));
    put_settings(returned, back, to_wire(back, mesh, starts));
    put_settings(plain, defaults, to_wire(defaults, mesh, {0, static_cast<uint32_t>(mesh.size())}));
    EXPECT_EQ(sent.SerializeAsString(), returned.SerializeAsString()) << "changed on its way";
    EXPECT_NE(sent.SerializeAsString(), plain.SerializeAsString()) << "the sample changed nothing";
  }
}

// A run's settings as their flags' text (the farm's job files, the status) read back to the same
// run, each row's sample and the defaults of the command lines and of the library (which meshes
// one patch per face: neither --patches nor --max-edge is written); what is not a run's
// setting is refused with the file's name.
TEST(SettingsTable, TheSettingsAsTextReadBackToTheSameRun) {
  const PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 200});
  const auto as_checkpoint = [&](const RunSettings& s) {
    std::vector<uint32_t> starts;
    for (uint32_t c = 0; c < s.chunks; ++c) starts.push_back(c);
    starts.push_back(static_cast<uint32_t>(mesh.size()));
    wire::Checkpoint c;
    put_settings(c, s, to_wire(s, mesh, starts));
    return c.SerializeAsString();
  };
  std::vector<RunSettings> runs = {from_flags({}), RunSettings{}};
  for (const auto& [flag, text] : kSamples) runs.push_back(from_flags({{flag, text}}));
  for (const RunSettings& s : runs) {
    const SettingsText text = settings_text(s);
    EXPECT_EQ(as_checkpoint(settings_from_text(text, "job.json")), as_checkpoint(s)) << fmt::format("{}", text.size());
    SettingsText reversed(text.rbegin(), text.rend());  // the table's order is the reader's
    EXPECT_EQ(as_checkpoint(settings_from_text(reversed, "job.json")), as_checkpoint(s));
  }
  const SettingsText library = settings_text(RunSettings{});
  EXPECT_TRUE(std::none_of(library.begin(), library.end(), [](const auto& t) { return t.first == "patches" || t.first == "max-edge"; }));
  auto refused = [](const SettingsText& text, const std::string& expect) {
    try {
      settings_from_text(text, "jobs/7/job.json");
      ADD_FAILURE() << expect << ": accepted";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), expect);
    }
  };
  refused({{"nodes", "3"}}, "jobs/7/job.json: 'nodes' is not a run setting");
  refused({{"seed", "1"}, {"seed", "2"}}, "jobs/7/job.json: 'seed' is given twice");
  refused({{"grid", "1"}}, "jobs/7/job.json: grid: must be in [2, 8192] (got 1)");
  refused({{"rule", "average"}, {"directions", "stratified"}},
          "jobs/7/job.json: directions: stratified needs --rule chain (under average it biases the estimate: engine/bundle.cpp)");
}

// The command lines' defaults come from the rows: 10,000 patches, 1,000 bundles, the chain rule
// with stratified directions, 0.25 shots per bundle; --directions auto follows --rule; a value a
// flag refuses names the flag; what no run can have is refused by check() from any source.
TEST(SettingsTable, DefaultsAndRefusalsComeFromTheRows) {
  const RunSettings d = from_flags({});
  EXPECT_EQ(d.mesh_options.target_patches, 10000u);
  EXPECT_EQ(d.bundles, 1000u);
  EXPECT_EQ(d.rule, UpdateRule::chain);
  EXPECT_EQ(d.directions, Directions::stratified);
  EXPECT_EQ(d.shots_per_bundle, 0.25);
  EXPECT_EQ(d.grid, 0);
  EXPECT_EQ(d.burn_in, -1);
  EXPECT_EQ(from_flags({{"rule", "average"}}).directions, Directions::random);
  EXPECT_EQ(from_flags({{"max-edge", "0.5"}}).mesh_options.target_patches, 0u);
  EXPECT_EQ(from_flags({{"target-error", "0.01"}}).bundles, static_cast<uint64_t>(cli::kTargetErrorCap));
  auto refused = [](const std::map<std::string, std::string>& given, const std::string& expect) {
    try {
      from_flags(given);
      ADD_FAILURE() << expect << ": accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
  };
  refused({{"rule", "average"}, {"directions", "stratified"}}, "--directions: stratified needs --rule chain");
  refused({{"patches", "10"}, {"max-edge", "1"}}, "--patches and --max-edge exclude each other");
  refused({{"grid", "1"}}, "--grid: must be in [2, 8192] (got 1)");
  refused({{"shot-resolution", "7"}}, "--shot-resolution: must be 0 (auto) or even");
  refused({{"exchange-fraction", "nan"}}, "--exchange-fraction: 'nan' is not a finite number");
  refused({{"seed", "-1"}}, "--seed: '-1' is not a whole number");
  RunSettings s;
  s.grid = 1;
  EXPECT_THROW(check(s), Error);
  s = {};
  s.fraction = 0;
  EXPECT_THROW(check(s), Error);
  s = {};
  s.rule = UpdateRule::average;
  s.directions = Directions::stratified;
  EXPECT_THROW(check(s), Error);
}

}  // namespace
}  // namespace sirad::cluster
