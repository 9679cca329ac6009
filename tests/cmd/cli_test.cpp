// sirad tests: the command line end to end: a real render writes the three outputs, and every
// kind of bad input ends with one clear line and a non-zero exit and leaves no file behind.
#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <set>
#include <string>
#include <thread>
#include <tuple>

#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfStandardAttributes.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <gtest/gtest.h>

#include "cluster/status.h"
#include "io/read_solution.h"
#include "tests/cli_fixture.h"
#include "tests/exr_content.h"
#include "tests/png_util.h"
#include "tests/test_folder.h"

namespace fs = std::filesystem;
using sirad::test::Cli;
using sirad::test::Outcome;

namespace {

const char* kTinyRoom = R"(mtllib room.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
usemtl lamp
f 4 3 7 8
usemtl wall
f 1 5 6 2
f 1 2 3 4
f 5 8 7 6
f 1 4 8 5
f 2 6 7 3
)";
const char* kTinyMtl = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl wall\nKd 0.5 0.5 0.5\n";

TEST_F(Cli, RenderWritesThreeOutputsAndSummary) {
  Outcome r = sirad("render cornell --patches 300 --bundles 16 --width 64 --height 64 --seed 3");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* ext : {".exr", ".png", ".ply"}) {
    EXPECT_TRUE(fs::exists(dir_ / (std::string("cornell") + ext))) << ext;
    EXPECT_NE(r.out.find((dir_ / (std::string("cornell") + ext)).string()), std::string::npos) << r.out;
  }
  EXPECT_NE(r.out.find("bundles/s"), std::string::npos);
  EXPECT_NE(r.out.find("line crossings/s"), std::string::npos);
  // The EXR header records the run's settings.
  Imf::InputFile exr((dir_ / "cornell.exr").string().c_str());
  auto* bundles = exr.header().findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
  auto* hash = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.scene_hash");
  ASSERT_NE(bundles, nullptr);
  ASSERT_NE(hash, nullptr);
  EXPECT_EQ(bundles->value(), 16);
  EXPECT_EQ(hash->value().size(), 32u);
  // OpenEXR's own reader accepts the file. (exrheader's exit status, not exrinfo's: Debian's
  // exrinfo 3.1 returns a random status on about one run in six for any file, ours or not.)
  EXPECT_EQ(std::system(("exrheader '" + (dir_ / "cornell.exr").string() + "' >/dev/null").c_str()), 0);
}

TEST_F(Cli, OneNodeStopsAtItsTargetError) {
  // The batch-means estimate needs 8 batches: at 5 % on 300 patches that is a few hundred
  // bundles of the 100000 allowed; the outputs record how many ran and the estimate reached.
  Outcome r = sirad("render cornell --patches 300 --bundles 100000 --target-error 0.05 --width 16 --height 16");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("ended early: target error"), std::string::npos) << r.out;
  Imf::InputFile exr((dir_ / "cornell.exr").string().c_str());
  auto* bundles = exr.header().findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
  auto* error = exr.header().findTypedAttribute<Imf::DoubleAttribute>("sirad.error_estimate");
  ASSERT_NE(bundles, nullptr);
  ASSERT_NE(error, nullptr);
  EXPECT_LT(bundles->value(), 100000);
  EXPECT_GT(bundles->value(), 64);
  EXPECT_LE(error->value(), 0.05);
}

// --target-error without --bundles lifts the default cap of 1000 bundles: 1.5 % on 300 patches
// takes a few thousand (measured 2,600-4,000). With a --bundles cap it cannot reach, the run
// says so on stdout and in the EXR (sirad.ended_by), and exits 0 with the result it has.
TEST_F(Cli, TargetErrorLiftsTheDefaultCapAndSaysWhenItFallsShort) {
  Outcome r = sirad("render cornell --patches 300 --target-error 0.015 --width 16 --height 16 --out lifted -q");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("ended early: target error"), std::string::npos) << r.out;
  {
    Imf::InputFile exr((dir_ / "lifted.exr").string().c_str());
    auto* bundles = exr.header().findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
    ASSERT_NE(bundles, nullptr);
    EXPECT_GT(bundles->value(), 1000) << "the default cap of 1000 bundles was not lifted";
  }
  Outcome s = sirad("render cornell --patches 300 --target-error 0.001 --bundles 64 --width 16 --height 16 --out capped -q");
  ASSERT_EQ(s.status, 0) << s.err;
  EXPECT_NE(s.out.find("ended short of the target: bundle cap 64 reached short of the target error 0.001"),
            std::string::npos) << s.out;
  Imf::InputFile exr((dir_ / "capped.exr").string().c_str());
  auto* ended = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.ended_by");
  ASSERT_NE(ended, nullptr);
  EXPECT_NE(ended->value().find("short of the target error"), std::string::npos) << ended->value();
  // The cluster says it in its status JSON too.
  Outcome c = sirad("render cornell --patches 300 --nodes 2 --exchange-every 4 --target-error 0.000001 --bundles 64 "
                    "--width 16 --height 16 --out cluster --status-json status.json -q");
  ASSERT_EQ(c.status, 0) << c.err;
  EXPECT_NE(c.out.find("ended short of the target"), std::string::npos) << c.out;
  const sirad::cluster::Status status = sirad::cluster::read_status((dir_ / "status.json").string());
  EXPECT_EQ(status.ended_by, "bundle cap reached short of the target error");
  EXPECT_EQ(status.target_error, 1e-6);
  // And every setting of the run, as the table spells it: those given, and the defaults.
  const std::map<std::string, std::string> settings(status.settings.begin(), status.settings.end());
  EXPECT_EQ(settings.size(), status.settings.size()) << "a setting twice";
  EXPECT_EQ(settings.at("patches"), "300");
  EXPECT_EQ(settings.at("bundles"), "64");
  EXPECT_EQ(settings.at("exchange-every"), "4");
  EXPECT_EQ(settings.at("target-error"), "1e-06");
  EXPECT_EQ(settings.at("shots-per-bundle"), "0.25");
  EXPECT_EQ(settings.at("directions"), "stratified");
  EXPECT_EQ(settings.count("grid"), 0u) << "auto: no text";
}

// No output ever overwrites the scene file that was read: a scene named like one of the outputs
// (NAME.ply) is refused before anything is read or written, and stays as it was.
// --warm-start from the same scene's PLY: every patch is found where it was, the result is the
// PLY's solution (the control variate cancels each bundle to the last bit: warm_start_test.cpp),
// its error is the previous run's (its PLY says it, and so does the new one); and what a warm
// start cannot do is refused in one line before any solve.
TEST_F(Cli, AWarmStartFromTheSameSceneKeepsItsSolution) {
  Outcome r = sirad("render cornell --patches 300 --bundles 256 --width 16 --height 16 --out before -q");
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string before = slurp((dir_ / "before.ply").string());
  ASSERT_NE(before.find("comment sirad error estimate "), std::string::npos);
  r = sirad("render cornell --patches 300 --bundles 64 --width 16 --height 16 --warm-start before.ply --out after");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("warm start from before.ply: 298 of 298 patches"), std::string::npos) << r.err;
  auto estimate = [](const std::string& ply) {
    const std::size_t at = ply.find("comment sirad error estimate ");
    return at == std::string::npos ? -1.0 : std::stod(ply.substr(at + 29, 24));
  };
  const std::string after = slurp((dir_ / "after.ply").string());
  EXPECT_DOUBLE_EQ(estimate(after), estimate(before));
  // The faces (after the header's comments) carry the same values.
  EXPECT_EQ(after.substr(after.find("element vertex")), before.substr(before.find("element vertex")));
  fs::create_directory(dir_ / "prev");  // out of the way of expect_error's check that a refusal writes nothing
  fs::rename(dir_ / "before.ply", dir_ / "prev" / "before.ply");
  for (const char* f : {"before.exr", "before.png", "before.glb", "after.exr", "after.png", "after.ply", "after.glb"}) fs::remove(dir_ / f);
  expect_error(sirad("render cornell --patches 300 --warm-start prev/before.glb"), "give the previous run's PLY");
  expect_error(sirad("render cornell --patches 300 --warm-start prev/before.ply --nodes 2"), "runs on one node");
  expect_error(sirad("render cornell --patches 300 --warm-start prev/before.ply --shots-per-bundle 1"), "takes no first shot");
  expect_error(sirad("render cornell --patches 300 --warm-start prev/missing.ply"), "missing.ply");
  expect_error(sirad("render cornell --patches 300 --warm-start prev/before.ply --target-error 0.001"), "cannot reach the target");
}

// --transfer picks the bundle engine's path on any device: a run on the wide path (16 bundles
// a step of the chain, Solver::step_batch) solves to the band path's answer within the two
// runs' own error estimates e_w and e_b (each the relative RMS error per patch): the relative
// RMS difference per patch is at most sqrt(e_w^2 + e_b^2) in expectation (independent errors;
// the runs share a seed, which only correlates them), held within 2x; the area-weighted means
// differ by at most that RMS (the mean of the errors is below their RMS), held within 3x.
TEST_F(Cli, TheTransferPathKeepsTheAnswer) {
  fs::create_directory(dir_ / "runs");  // out of the way of expect_error's check that a refusal writes nothing
  for (const char* path : {"band", "wide"}) {
    Outcome r = sirad(fmt::format("render cornell --patches 300 --bundles 1024 --width 8 --height 8 --transfer {} --out runs/{} -q", path, path));
    ASSERT_EQ(r.status, 0) << r.err;
  }
  const sirad::Solution band = sirad::read_solution((dir_ / "runs" / "band.ply").string()),
                       wide = sirad::read_solution((dir_ / "runs" / "wide.ply").string());
  ASSERT_EQ(band.radiosity.size(), wide.radiosity.size());
  ASSERT_TRUE(band.error_estimate && wide.error_estimate);
  const double e = std::hypot(*band.error_estimate, *wide.error_estimate);
  ASSERT_GT(e, 0.0);
  double sq = 0, weight = 0, sum_b = 0, sum_w = 0;
  for (std::size_t j = 0; j < band.radiosity.size(); ++j) {
    if (band.mesh.emits(j)) continue;
    const double a = band.mesh.area[j];
    const double yb = band.radiosity[j].x + band.radiosity[j].y + band.radiosity[j].z;
    const double yw = wide.radiosity[j].x + wide.radiosity[j].y + wide.radiosity[j].z;
    ASSERT_GT(yb, 0.0) << "patch " << j;
    sq += a * (yw / yb - 1) * (yw / yb - 1);
    weight += a;
    sum_b += a * yb;
    sum_w += a * yw;
  }
  const double rms = std::sqrt(sq / weight);
  std::printf("band and wide paths: relative RMS difference %.4f, means %+.4f, estimates %.4f and %.4f\n", rms,
              sum_w / sum_b - 1, *band.error_estimate, *wide.error_estimate);
  EXPECT_LT(rms, 2 * e) << "estimates " << *band.error_estimate << " and " << *wide.error_estimate;
  EXPECT_GT(rms, 0.0) << "the wide path's batches make another chain: the two runs cannot be the same bits";
  EXPECT_LT(std::abs(sum_w / sum_b - 1), 3 * e);
  expect_error(sirad("render cornell --patches 300 --transfer narrow"), "--transfer");
}

TEST_F(Cli, OutputsNeverOverwriteTheScene) {
  write("room.ply", "ply\nformat ascii 1.0\nend_header\n");
  Outcome r = sirad("render room.ply --bundles 4");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("would overwrite the scene file"), std::string::npos) << r.err;
  EXPECT_EQ(slurp((dir_ / "room.ply").string()), "ply\nformat ascii 1.0\nend_header\n");
}

// The camera: --camera sets the view and is stored in the EXR (sirad.camera, and where it came
// from in sirad.camera_from) and printed with the outputs; a
// scene without a camera line gets one chosen to see the most (a closed room: from inside, where
// every ray of the view meets a wall's front), printed with how much it sees; a bad --camera is
// one line naming the flag and what is wrong.
TEST_F(Cli, CameraFromTheFlagTheSceneOrChosen) {
  write("room.mtl", kTinyMtl);
  write("room.obj", kTinyRoom);
  for (const char* bad : {"'eye 0 0 0 look 0 0 0 up 0 1 0 fov 40'", "'eye 0 0 0 look 0 0 1 up 0 1 0'",
                          "'eye 0 0 0 look 0 0 1 up 0 1 0 fov 200'", "'eye 0 0 x look 0 0 1 up 0 1 0 fov 40'"}) {
    SCOPED_TRACE(bad);
    expect_error(sirad(std::string("render room.obj --bundles 4 --camera ") + bad), "--camera");
  }
  Outcome given = sirad("render room.obj --patches 200 --bundles 8 --width 8 --height 8 --out given "
                        "--camera 'eye 0.5 0.5 0.2 look 0.5 0.5 1 up 0 1 0 fov 50'");
  ASSERT_EQ(given.status, 0) << given.err;
  EXPECT_NE(given.out.find("camera eye 0.5 0.5 0.2 look 0.5 0.5 1 up 0 1 0 fov 50 (--camera)\n"), std::string::npos)
      << given.out;
  {
    Imf::InputFile exr((dir_ / "given.exr").string().c_str());
    auto* camera = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.camera");
    ASSERT_NE(camera, nullptr);
    EXPECT_EQ(camera->value(), "eye 0.5 0.5 0.2 look 0.5 0.5 1 up 0 1 0 fov 50");
  }
  Outcome chosen = sirad("render room.obj --patches 200 --bundles 8 --width 8 --height 8 --out chosen");
  ASSERT_EQ(chosen.status, 0) << chosen.err;
  EXPECT_NE(chosen.out.find("(chosen: it sees a surface on 100 % of the view)"), std::string::npos) << chosen.out;
  Imf::InputFile exr((dir_ / "chosen.exr").string().c_str());
  auto* camera = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.camera");
  ASSERT_NE(camera, nullptr);
}

// The images take the shape of the scene's camera (Blender's 3:2 in the apartment's glb: 768 x
// 512), or the one side given and the camera's aspect; `sirad image` of the glb a run wrote keeps it.
TEST_F(Cli, ImagesTakeTheCamerasShape) {
  const std::string scene = std::string(SIRAD_SOURCE_DIR) + "/tests/data/blender/apartment.glb";
  Outcome r = sirad("render '" + scene + "' --patches 400 --bundles 4 --out flat");
  ASSERT_EQ(r.status, 0) << r.err;
  int w = 0, h = 0;
  sirad::test::read_png((dir_ / "flat.png").string(), w, h);
  EXPECT_EQ(w, 768);
  EXPECT_EQ(h, 512);
  r = sirad("render '" + scene + "' --patches 400 --bundles 4 --width 300 --out narrow");
  ASSERT_EQ(r.status, 0) << r.err;
  sirad::test::read_png((dir_ / "narrow.png").string(), w, h);
  EXPECT_EQ(w, 300);
  EXPECT_EQ(h, 200);
  r = sirad("image narrow.glb --spp 1 --height 30 --out again");
  ASSERT_EQ(r.status, 0) << r.err;
  sirad::test::read_png((dir_ / "again.png").string(), w, h);
  EXPECT_EQ(w, 45);
  EXPECT_EQ(h, 30);
}

// A flag that has no effect in a mode is refused, never ignored: cluster settings on one node,
// a target error that no estimate of the mode can reach (the average rule's spread of the
// nodes' states, in a cluster that exchanges only at the end).
TEST_F(Cli, FlagsWithoutEffectAreRefused) {
  for (const char* flag : {"--exchange-every 8", "--exchange-fraction 0.5", "--topology ring", "--mode sync",
                           "--balance off", "--chunks 4", "--status-json s.json"}) {
    SCOPED_TRACE(flag);
    expect_error(sirad(std::string("render furnace --patches 50 --bundles 4 ") + flag), "has no effect on one node");
  }
  expect_error(sirad("render furnace --patches 50 --bundles 4 --nodes 2 --rule average --target-error 0.1"), "--exchange-every");
  expect_error(sirad("emulate furnace --patches 50 --bundles 4 --nodes 2 --rule average --target-error 0.1"), "--exchange-every");
}

// Under the chain rule a cluster ends at its target error in every mode: with exchanges only at
// the end the nodes' own batch-means estimates, reported with each grant (at most 64 bundles
// then), combine into the run's (sqrt(sum n_p^2 e_p^2) / sum n_p), so 2 % on 300 patches ends
// long before the cap of 100,000 bundles, with the status and the EXR saying so; on one node
// too, and in the virtual-time cluster.
TEST_F(Cli, ClusterTargetErrorWorksWithoutExchanges) {
  for (const char* run : {"render cornell --nodes 2", "render cornell --nodes 1", "render cornell --nodes 2 --mode sync",
                          "emulate cornell --nodes 4 --bundle-ms 1"}) {
    SCOPED_TRACE(run);
    Outcome r = sirad(std::string(run) + " --patches 300 --bundles 100000 --target-error 0.02 --width 16 --height 16 "
                                         "--out target -q");
    ASSERT_EQ(r.status, 0) << r.err;
    Imf::InputFile exr((dir_ / "target.exr").string().c_str());
    const std::string ended = exr.header().typedAttribute<Imf::StringAttribute>("sirad.ended_by").value();
    EXPECT_EQ(ended.rfind("target error (", 0), 0u) << ended;
    const int bundles = exr.header().typedAttribute<Imf::IntAttribute>("sirad.bundles").value();
    EXPECT_LT(bundles, 20000);
    EXPECT_GT(bundles, 100);
  }
}

TEST_F(Cli, EmbeddedClusterRendersWithTwoNodes) {
  Outcome r = sirad("render cornell --nodes 2 --patches 300 --bundles 40 --exchange-every 10 --width 32 --height 32 "
                    "--status-json status.json");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* ext : {".exr", ".png", ".ply"}) EXPECT_TRUE(fs::exists(dir_ / (std::string("cornell") + ext))) << ext;
  EXPECT_NE(r.out.find("node local-0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("node local-1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("nodes 2"), std::string::npos) << r.out;
  Imf::InputFile exr((dir_ / "cornell.exr").string().c_str());
  auto* nodes = exr.header().findTypedAttribute<Imf::IntAttribute>("sirad.nodes");
  ASSERT_NE(nodes, nullptr);
  EXPECT_EQ(nodes->value(), 2);
  // The status file's last rewrite: every bundle done, both nodes listed.
  std::string status = slurp((dir_ / "status.json").string());
  const sirad::cluster::Status st = sirad::cluster::read_status((dir_ / "status.json").string());
  EXPECT_EQ(st.bundles_done, 40u) << status;
  EXPECT_EQ(st.bundles, 40u) << status;
  ASSERT_EQ(st.nodes.size(), 2u) << status;
  // In join order, which is whichever node thread said HELLO first.
  EXPECT_EQ(std::set<std::string>({st.nodes[0].name, st.nodes[1].name}), std::set<std::string>({"local-0", "local-1"})) << status;
  fs::remove(dir_ / "status.json");
}

// sirad emulate: the virtual-time cluster with the hetero-16 profile writes the three outputs,
// the per-node CSV (16 nodes from the profile's entries; the 4x node does more bundles than the
// 0.25x one) and the timeline; the EXR says it was emulated.
TEST_F(Cli, EmulateRunsTheHeterogeneousProfileInVirtualTime) {
  Outcome r = sirad(std::string("emulate cornell --profile ") + SIRAD_SOURCE_DIR +
                    "/deploy/profiles/hetero-16.yaml --patches 300 --bundles 480 --exchange-every 8 --bundle-ms 20 "
                    "--shots-per-bundle 0 --directions random "
                    "--width 32 --height 32 --out emu --nodes-csv nodes.csv --timeline timeline.csv");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* ext : {".exr", ".png", ".ply"}) EXPECT_TRUE(fs::exists(dir_ / (std::string("emu") + ext))) << ext;
  EXPECT_NE(r.out.find("virtual wall time"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("node emu-15"), std::string::npos) << r.out;
  std::ifstream csv(dir_ / "nodes.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "node,speed,slowdown,bundles,exchanges,ready_s,busy_s,idle_s,utilisation,end_s");
  std::map<double, uint64_t> by_speed;  // the bundles of the last node of each speed
  int rows = 0;
  while (std::getline(csv, line)) {
    ++rows;
    std::stringstream ss(line);
    std::string name, speed, slowdown, bundles;
    std::getline(ss, name, ',');
    std::getline(ss, speed, ',');
    std::getline(ss, slowdown, ',');
    std::getline(ss, bundles, ',');
    by_speed[std::stod(speed)] = std::stoull(bundles);
  }
  EXPECT_EQ(rows, 16);
  ASSERT_TRUE(by_speed.count(0.25) && by_speed.count(4.0));
  EXPECT_GT(by_speed[4.0], by_speed[0.25]);
  std::string timeline = slurp((dir_ / "timeline.csv").string());
  EXPECT_EQ(timeline.rfind("t,node,event,bundles\n", 0), 0u);
  EXPECT_NE(timeline.find(",grant,"), std::string::npos);
  Imf::InputFile exr((dir_ / "emu.exr").string().c_str());
  auto* emulated = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.emulated");
  ASSERT_NE(emulated, nullptr);
  EXPECT_EQ(emulated->value(), "virtual time");
  fs::remove(dir_ / "nodes.csv");
  fs::remove(dir_ / "timeline.csv");
}

// `sirad emulate --final-gather`: the image follows the solve in tiles that the emulated nodes
// render (the timeline has their TILES and PIXELS), and it is the image `sirad image` makes of
// the solution the run wrote, bit for bit (a pixel depends only on the seed and its place).
TEST_F(Cli, AnEmulatedClustersImageIsTheImageOfItsSolution) {
  Outcome e = sirad("emulate cornell --nodes 3 --patches 300 --bundles 48 --bundle-ms 1 --tile-ms 2 --width 70 --height 40 "
                    "--final-gather 4 --timeline tl.csv --out emu");
  ASSERT_EQ(e.status, 0) << e.err;
  EXPECT_NE(e.out.find("image: 6 tiles in "), std::string::npos) << e.out;
  const std::string timeline = slurp((dir_ / "tl.csv").string());
  EXPECT_NE(timeline.find(",tiles,"), std::string::npos);
  EXPECT_NE(timeline.find(",pixels,"), std::string::npos);
  Outcome i = sirad("image emu.ply --width 70 --height 40 --spp 4 --out again -q");
  ASSERT_EQ(i.status, 0) << i.err;
  const auto emulated = sirad::test::exr_channels(dir_ / "emu.exr"), imaged = sirad::test::exr_channels(dir_ / "again.exr");
  for (const char* c : {"R", "G", "B", "direct.R", "indirect.R"}) {
    ASSERT_TRUE(emulated.count(c)) << c;
    EXPECT_EQ(emulated.at(c), imaged.at(c)) << c;
  }
}

// On unequal nodes an async run's fast nodes do not wait for the slow ones' set-up: on hetero-16
// the first grant to a 4x node (emu-0) goes out before the 0.25x nodes (emu-14, emu-15; their
// burn-in takes 16 times as long) are ready. A sync run waits for every node (its rounds need
// them), so there no grant precedes the last READY.
TEST_F(Cli, EmulatedFastNodesDoNotWaitForSlowOnesSetUp) {
  for (const char* mode : {"async", "sync"}) {
    Outcome r = sirad(std::string("emulate cornell --profile ") + SIRAD_SOURCE_DIR +
                      "/deploy/profiles/hetero-16.yaml --patches 300 --bundles 480 --exchange-every 8 --bundle-ms 20 "
                      "--width 8 --height 8 --out emu --mode " + mode + " --timeline timeline.csv");
    ASSERT_EQ(r.status, 0) << r.err;
    std::ifstream csv(dir_ / "timeline.csv");
    std::string line;
    std::getline(csv, line);
    double first_grant = -1, last_ready = -1;
    while (std::getline(csv, line)) {
      std::stringstream ss(line);
      std::string t, node, event;
      std::getline(ss, t, ',');
      std::getline(ss, node, ',');
      std::getline(ss, event, ',');
      if (event == "grant" && node == "0" && first_grant < 0) first_grant = std::stod(t);
      if (event == "ready") last_ready = std::max(last_ready, std::stod(t));
    }
    ASSERT_GE(first_grant, 0) << mode;
    if (std::string(mode) == "async") EXPECT_LT(first_grant, last_ready) << mode;
    else EXPECT_GE(first_grant, last_ready) << mode;
  }
  fs::remove(dir_ / "timeline.csv");
}

TEST_F(Cli, EmulateNeedsNodesOrAProfileWithNodes) {
  expect_error(sirad("emulate cornell --bundles 8"), "--nodes");
  write("drops.yaml", "nodes:\n  - {index: 0, disconnect_at_s: 2}\n");
  expect_error(sirad("emulate furnace --patches 50 --bundles 8 --nodes 2 --profile drops.yaml"), "disconnects are not emulated");
  // 4096 solvers of 100,000 patches: ~420 GiB, refused before any is built.
  expect_error(sirad("emulate cornell --patches 100000 --bundles 8 --nodes 4096"), "GiB of solver state");
}

// --directions: recorded in the EXR header, single node and embedded cluster; stratified needs
// the chain rule.
TEST_F(Cli, DirectionsAreRecordedAndStratifiedNeedsTheChainRule) {
  for (const char* nodes : {"", " --nodes 2 --exchange-every 28"}) {
    Outcome r = sirad(std::string("render cornell --patches 300 --bundles 56 --width 16 --height 16 --directions stratified") +
                      nodes);
    ASSERT_EQ(r.status, 0) << r.err;
    Imf::InputFile exr((dir_ / "cornell.exr").string().c_str());
    auto* d = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.directions");
    ASSERT_NE(d, nullptr) << nodes;
    EXPECT_EQ(d->value(), "stratified") << nodes;
    for (const char* ext : {".exr", ".png", ".ply"}) fs::remove(dir_ / (std::string("cornell") + ext));
  }
  expect_error(sirad("render cornell --bundles 4 --directions stratified --rule average"), "--directions");
  expect_error(sirad("render cornell --bundles 4 --directions sobol"), "--directions");
  // The default, auto: stratified under the chain rule, random under average; the control
  // variate's setting is recorded too.
  for (auto [flags, directions, cv] : {std::tuple{"", "stratified", "on"}, {" --rule average", "random", "on"},
                                       {" --control-variate off", "stratified", "off"}}) {
    Outcome r = sirad(std::string("render cornell --patches 300 --bundles 30 --width 16 --height 16") + flags);
    ASSERT_EQ(r.status, 0) << r.err;
    Imf::InputFile exr((dir_ / "cornell.exr").string().c_str());
    auto* d = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.directions");
    auto* c = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.control_variate");
    ASSERT_NE(d, nullptr) << flags;
    ASSERT_NE(c, nullptr) << flags;
    EXPECT_EQ(d->value(), directions) << flags;
    EXPECT_EQ(c->value(), cv) << flags;
    for (const char* ext : {".exr", ".png", ".ply"}) fs::remove(dir_ / (std::string("cornell") + ext));
  }
  expect_error(sirad("render cornell --bundles 4 --control-variate maybe"), "--control-variate");
}

// The EXR's pixels and attributes too, but for the run's time and rates (sirad.seconds,
// sirad.*_per_s: the clock's), which it must have.
TEST_F(Cli, SameSeedGivesBitwiseIdenticalFiles) {
  ASSERT_EQ(sirad("render cornell --patches 300 --bundles 12 --width 48 --height 48 --out a").status, 0);
  ASSERT_EQ(sirad("render cornell --patches 300 --bundles 12 --width 48 --height 48 --out b").status, 0);
  for (const char* ext : {".png", ".ply"})
    EXPECT_EQ(slurp((dir_ / (std::string("a") + ext)).string()), slurp((dir_ / (std::string("b") + ext)).string()))
        << ext;
  const std::string a = sirad::test::exr_content(dir_ / "a.exr");
  EXPECT_EQ(a, sirad::test::exr_content(dir_ / "b.exr"));
  for (const char* name : {"sirad.bundles int 12", "sirad.patches int ", "sirad.scene_hash"}) EXPECT_NE(a.find(name), std::string::npos) << name;
  Imf::InputFile exr((dir_ / "a.exr").string().c_str());
  for (const char* name : {"sirad.seconds", "sirad.bundles_per_s", "sirad.patch_bundles_per_s", "sirad.crossings_per_s"}) {
    auto* v = exr.header().findTypedAttribute<Imf::DoubleAttribute>(name);
    ASSERT_NE(v, nullptr) << name;
    EXPECT_GT(v->value(), 0) << name;
  }
  const double bundles_per_s = exr.header().typedAttribute<Imf::DoubleAttribute>("sirad.bundles_per_s").value();
  const double patches = exr.header().typedAttribute<Imf::IntAttribute>("sirad.patches").value();
  EXPECT_DOUBLE_EQ(exr.header().typedAttribute<Imf::DoubleAttribute>("sirad.patch_bundles_per_s").value(), bundles_per_s * patches);
}

// A room made from a cube with its normals out (as a default cube in Blender) and a lamp plane
// facing the ceiling: without --two-sided the run warns, naming each object, that the room
// looks inside out and the lamp lights nothing (and the image is black); a texture map is
// named as not read. With --two-sided (every face both ways, as Cycles) the room is lit and
// neither orientation warning is given.
TEST_F(Cli, InsideOutSceneWarnsAndTwoSidedLightsIt) {
  write("cube.obj",
        "mtllib cube.mtl\no Room\nusemtl wall\n"
        "v -2 -2 -2\nv 2 -2 -2\nv 2 2 -2\nv -2 2 -2\nv -2 -2 2\nv 2 -2 2\nv 2 2 2\nv -2 2 2\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n"
        "o Lamp\nusemtl lamp\nv -0.5 1.9 -0.5\nv 0.5 1.9 -0.5\nv 0.5 1.9 0.5\nv -0.5 1.9 0.5\nf 9 12 11 10\n");
  write("cube.mtl", "newmtl wall\nKd 0.8 0.8 0.8\nmap_Kd wood.png\nnewmtl lamp\nKd 0 0 0\nKe 5 5 5\n");
  Outcome one = sirad("render cube.obj --patches 400 --bundles 32 --width 8 --height 8 --out one -q");
  ASSERT_EQ(one.status, 0) << one.err;
  EXPECT_NE(one.err.find("warning: object 'Room' (material 'wall') looks inside out"), std::string::npos) << one.err;
  EXPECT_NE(one.err.find("warning: object 'Lamp' (material 'lamp') emits but lights nothing"), std::string::npos) << one.err;
  EXPECT_NE(one.err.find("texture maps are not read (wood.png)"), std::string::npos) << one.err;
  Outcome two = sirad("render cube.obj --patches 400 --bundles 32 --width 8 --height 8 --out two -q --two-sided");
  ASSERT_EQ(two.status, 0) << two.err;
  EXPECT_EQ(two.err.find("inside out"), std::string::npos) << two.err;
  EXPECT_EQ(two.err.find("lights nothing"), std::string::npos) << two.err;
  EXPECT_NE(two.err.find("texture maps are not read"), std::string::npos) << two.err;
  // The error estimate exists only where something is lit: n/a for the black room.
  EXPECT_NE(one.out.find("error estimate n/a"), std::string::npos) << one.out;
  EXPECT_EQ(two.out.find("error estimate n/a"), std::string::npos) << two.out;
}

TEST_F(Cli, MissingSceneFile) { expect_error(sirad("render nothere.obj --bundles 4"), "nothere.obj"); }

TEST_F(Cli, MalformedSceneFile) {
  write("bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n");
  expect_error(sirad("render bad.obj --bundles 4"), "bad.obj");
}

TEST_F(Cli, EmptyScene) {
  write("empty.obj", "");
  expect_error(sirad("render empty.obj --bundles 4"), "empty.obj");
}

TEST_F(Cli, SceneWithoutEmitter) {
  write("dark.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expect_error(sirad("render dark.obj --bundles 4"), "emitter");
}

TEST_F(Cli, NanVertex) {
  write("room.mtl", kTinyMtl);
  std::string obj = kTinyRoom;
  obj.replace(obj.find("v 1 1 1"), 7, "v nan 1 1");
  write("nan.obj", obj);
  expect_error(sirad("render nan.obj --bundles 4"), "nan.obj");
}

TEST_F(Cli, DegenerateTriangleRefusedOrSkipped) {
  write("room.mtl", kTinyMtl);
  write("degenerate.obj", std::string(kTinyRoom) + "v 0.5 0.5 0.5\nf 9 9 9\n");
  expect_error(sirad("render degenerate.obj --bundles 4"), "degenerate.obj");
  Outcome r = sirad("render degenerate.obj --bundles 4 --patches 50 --width 16 --height 16 --skip-degenerate");
  EXPECT_EQ(r.status, 0) << r.err;
}

TEST_F(Cli, NonsensicalFlags) {
  expect_error(sirad("render cornell --grid 0"), "--grid");
  expect_error(sirad("render cornell --bundles -5"), "--bundles");
  expect_error(sirad("render cornell --bundles 0"), "--bundles");
  expect_error(sirad("render cornell --patches 0"), "--patches");
  expect_error(sirad("render cornell --rule sideways"), "--rule");
  expect_error(sirad("render cornell --bundles lots"), "--bundles");
  expect_error(sirad("render cornell --frobnicate"), "frobnicate");
  expect_error(sirad("render cornell --out no/such/dir/x --bundles 2"), "no/such/dir");
  expect_error(sirad("render cornell --nodes 2 --exchange-every often"), "--exchange-every");
  expect_error(sirad("render cornell --nodes 2 --topology mesh"), "--topology");
  // CLI11's Range lets NaN through (every comparison with it is false): the floating-point
  // flags are refused before anything runs, not when their value is first used.
  expect_error(sirad("render cornell --patches 200 --bundles 4 --exposure nan"), "--exposure");
  expect_error(sirad("render cornell --patches 200 --bundles 4 --exposure inf"), "--exposure");
  expect_error(sirad("render cornell --patches 200 --bundles 4 --target-error nan"), "--target-error");
  expect_error(sirad("render cornell --patches 200 --bundles 4 --shots-per-bundle nan"), "--shots-per-bundle");
  expect_error(sirad("render cornell --patches 200 --bundles 4 --nodes 2 --exchange-fraction nan"), "--exchange-fraction");
}

// CURVE keys (issue 6): keygen writes a public file and a secret one readable by its owner only,
// never overwrites, and the key files it writes are accepted; over TCP both programs need keys
// or an explicit --insecure (which says so on start); a secret key others may read, a broken
// key, a malformed allow list and keys together with --insecure are each one line.
TEST_F(Cli, KeysAndTheInsecureFlag) {
  Outcome k = sirad("keygen coord");
  ASSERT_EQ(k.status, 0) << k.err;
  EXPECT_EQ(fs::status(dir_ / "coord.key_secret").permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
  EXPECT_TRUE(fs::exists(dir_ / "coord.key"));
  expect_error(sirad("keygen coord"), "coord.key: exists");
  ASSERT_EQ(sirad("keygen n1").status, 0);
  std::string line = k.out.substr(k.out.find("allow-list line: ") + 17);
  write("allow", "# the farm\n" + line.substr(0, line.find('\n')) + "\n");
  const std::string coordinator = SIRAD_COORDINATOR_BINARY, node = SIRAD_NODE_BINARY;
  const std::string listen = "furnace --patches 50 --listen tcp://127.0.0.1:5555 --check-config";
  EXPECT_EQ(program(coordinator, listen + " --curve-secret coord.key_secret --allow allow").status, 0);
  expect_error(program(coordinator, listen), "--insecure", "sirad-coordinator");
  expect_error(program(coordinator, listen + " --insecure --curve-secret coord.key_secret --allow allow"), "choose one",
               "sirad-coordinator");
  write("bad-allow", "not-a-key node-a\n");
  expect_error(program(coordinator, listen + " --curve-secret coord.key_secret --allow bad-allow"), "bad-allow:1:",
               "sirad-coordinator");
  const std::string connect = "--connect tcp://127.0.0.1:5555 --check-config";
  EXPECT_EQ(program(node, connect + " --curve-secret n1.key_secret --server-key coord.key").status, 0);
  expect_error(program(node, connect), "--insecure", "sirad-node");
  fs::permissions(dir_ / "n1.key_secret", fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::others_read);
  expect_error(program(node, connect + " --curve-secret n1.key_secret --server-key coord.key"), "mode 0644", "sirad-node");
  write("broken.key_secret", "metadata\ncurve\n    public-key = \"short\"\n");
  fs::permissions(dir_ / "broken.key_secret", fs::perms::owner_read | fs::perms::owner_write);
  expect_error(program(node, connect + " --curve-secret broken.key_secret --server-key coord.key"), "broken.key_secret:3:",
               "sirad-node");
  Outcome insecure = program(node, connect + " --insecure");
  EXPECT_EQ(insecure.status, 0) << insecure.err;
  // Over inproc or ipc no keys are needed; the embedded default has none.
  EXPECT_EQ(program(node, "--connect ipc:///tmp/sirad-x --check-config").status, 0);
}

// --resume with a file that is not a checkpoint, or none, is one line naming the file; a flag
// that would change the resumed run's settings is refused.
TEST_F(Cli, ResumeRefusesWhatIsNotACheckpoint) {
  const std::string coordinator = SIRAD_COORDINATOR_BINARY;
  write("junk.checkpoint", "this is not a checkpoint");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --resume junk.checkpoint"),
               "junk.checkpoint: not a sirad checkpoint", "sirad-coordinator");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --resume none.checkpoint"),
               "none.checkpoint: cannot read the checkpoint", "sirad-coordinator");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --resume junk.checkpoint "
                                    "--bundles 50"),
               "--bundles with --resume", "sirad-coordinator");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --ledger no/such/ledger.csv"),
               "--ledger no/such/ledger.csv: directory 'no/such' does not exist", "sirad-coordinator");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --checkpoint no/such/c"),
               "--checkpoint no/such/c: directory 'no/such' does not exist", "sirad-coordinator");
  expect_error(program(coordinator, "furnace --listen tcp://127.0.0.1:5555 --insecure --check-config --checkpoint c "
                                    "--checkpoint-every nan"),
               "--checkpoint-every: 'nan' is not a finite number", "sirad-coordinator");
}

// Emulation profiles and the run-ending flags: bad ones are one line naming file, line and key.
TEST_F(Cli, BadProfilesAndEndingFlags) {
  write("slow.yaml", "defaults:\n  speed: 0\n");
  expect_error(sirad("render cornell --nodes 2 --profile slow.yaml"), "slow.yaml:2: defaults.speed: 0 is not in");
  write("typo.yaml", "nodes:\n  - name: a\n    latency: 3\n");
  expect_error(sirad("render cornell --nodes 2 --profile typo.yaml"), "typo.yaml:3: nodes[0].latency: unknown key");
  expect_error(sirad("render cornell --nodes 2 --profile none.yaml"), "none.yaml: cannot read the profile");
  expect_error(sirad("render cornell --profile " SIRAD_SOURCE_DIR "/deploy/profiles/lan-1g.yaml"), "needs a cluster");
  expect_error(sirad("render cornell --target-error 2"), "--target-error");
  expect_error(sirad("render cornell --shots-per-bundle -1"), "--shots-per-bundle");
  expect_error(sirad("render cornell --shot-resolution 7"), "--shot-resolution: must be 0 (auto) or even");
  expect_error(sirad("render cornell --nodes 2 --target-error 2"), "--target-error");
  expect_error(sirad("profile typo.yaml"), "typo.yaml:3");
  Outcome ok = sirad("profile " SIRAD_SOURCE_DIR "/deploy/profiles/office-mixed.yaml --nodes 4");
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_NE(ok.out.find("3 local-3 0.5 4 0.5 0.2 100 100 0 -1 -1"), std::string::npos) << ok.out;
}

TEST_F(Cli, DeviceByIndexNameAndEnvironment) {
  const std::string args = "render furnace --patches 60 --bundles 2 --width 8 --height 8 -q";
  expect_error(sirad(args + " --device 7:3"), "7:3");
  expect_error(sirad(args, "SIRAD_DEVICE=NoSuchDevice"), "NoSuchDevice");
  EXPECT_EQ(sirad(args + " --device 0:0").status, 0);
  EXPECT_EQ(sirad(args + " --device portable").status, 0);  // PoCL's platform name, any case
  EXPECT_EQ(sirad(args, "SIRAD_DEVICE=0:0").status, 0);
}

TEST_F(Cli, UnknownDevice) { expect_error(sirad("render cornell --bundles 2 --device NoSuchDevice"), "NoSuchDevice"); }

TEST_F(Cli, NoOpenClPlatform) {
  // An empty ICD vendor directory: the loader finds no platform.
  fs::create_directories(dir_ / "icd");
  expect_error(sirad("render cornell --bundles 2 --patches 100", "OCL_ICD_VENDORS='" + (dir_ / "icd").string() + "'"),
               "no OpenCL platform");
}

}  // namespace

// A camera that no float ray can place (an eye 1e20 away: Embree aborts the process on such a
// ray's origin) is refused with one line where the view meets the scene: as a flag of `image`
// and of `render`, and as a scene file's camera line. An eye 1e3 radii away (a telephoto view)
// still renders.
TEST_F(Cli, ACameraBeyondTheScenesReachIsRefusedNotAborted) {
  Outcome r = sirad("render cornell --patches 200 --bundles 8 -q");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"cornell.exr", "cornell.png", "cornell.glb"}) fs::remove(dir_ / f);
  fs::create_directory(dir_ / "in");  // (out of expect_error's sight: it finds no output in dir_)
  fs::rename(dir_ / "cornell.ply", dir_ / "in" / "solved.ply");
  const std::string far = "--camera 'eye 1e20 0 0 look 0 0 0 up 0 1 0 fov 60' --width 16 --height 16";
  expect_error(sirad("image in/solved.ply " + far + " --spp 1 --out far"), "the camera's eye is 1e+20 from the scene's centre");
  expect_error(sirad("render cornell --patches 200 --bundles 8 --final-gather 1 " + far), "--camera");
  expect_error(sirad("image in/solved.ply --camera 'eye inf 0 0 look 0 0 0 up 0 1 0 fov 60' --spp 1 --out far"), "camera");
  write("room.mtl", kTinyMtl);
  write("room.obj", std::string("# sirad camera eye 0.5 0.5 3e19 look 0.5 0.5 0.5 up 0 1 0 fov 40\n") + kTinyRoom);
  expect_error(sirad("render room.obj --bundles 4 --final-gather 1 --width 8 --height 8"), "room.obj: its camera");
  // An image too large for memory is refused when the flags are read, before any solve.
  expect_error(sirad("render cornell --patches 200 --bundles 8 --width 16384 --height 16384"), "more than 33554432 pixels");
  expect_error(sirad("image in/solved.ply --width 16384 --height 16384 --spp 1"), "more than 33554432 pixels");
  Outcome tele = sirad("image in/solved.ply --camera 'eye 278 273 -5e5 look 278 273 0 up 0 1 0 fov 0.1' --width 8 --height 8 --spp 1 --out tele -q");
  EXPECT_EQ(tele.status, 0) << tele.err;
}

// A solution is enough to image later: `sirad render --final-gather` and `sirad image` of the
// PLY that render wrote give the same passes bit for bit (the PLY keeps the faces, their
// radiosity, the camera and the background); combined = direct + indirect; a walkthrough file
// images each of its views; a PLY that is a scene, not a solution, and a bad view are refused
// with one line naming them.
TEST_F(Cli, ImageOfAStoredSolutionIsTheRendersFinalGather) {
  Outcome r = sirad("render cornell --patches 400 --bundles 64 --width 24 --height 20 --final-gather 4 -q");
  ASSERT_EQ(r.status, 0) << r.err;
  Outcome i = sirad("image cornell.ply --width 24 --height 20 --spp 4 --out again");
  ASSERT_EQ(i.status, 0) << i.err;
  const auto rendered = sirad::test::exr_channels(dir_ / "cornell.exr"), imaged = sirad::test::exr_channels(dir_ / "again.exr");
  for (const char* c : {"R", "G", "B", "direct.R", "direct.G", "direct.B", "indirect.R", "indirect.G", "indirect.B"}) {
    ASSERT_TRUE(rendered.count(c)) << c;
    EXPECT_EQ(rendered.at(c), imaged.at(c)) << c;
  }
  const std::vector<float>& red = imaged.at("R");
  for (std::size_t k = 0; k < red.size(); ++k) EXPECT_NEAR(red[k], imaged.at("direct.R")[k] + imaged.at("indirect.R")[k], 1e-5f);
  EXPECT_GT(*std::max_element(imaged.at("indirect.R").begin(), imaged.at("indirect.R").end()), 0.0f);
  EXPECT_TRUE(fs::exists(dir_ / "again.png"));
  // Two embedded nodes render the tiles on half the machine's cores each (not every core each).
  Outcome two = sirad("render cornell --patches 400 --bundles 64 --width 24 --height 20 --final-gather 4 --nodes 2 --out two");
  ASSERT_EQ(two.status, 0) << two.err;
  const int half = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / 2);
  EXPECT_NE(two.err.find(fmt::format("image: 24x20, 4 spp, 1 tiles, {} threads", half)), std::string::npos) << two.err;
  // The .glb the render wrote is a solution as well: the same image.
  Outcome g = sirad("image cornell.glb --width 24 --height 20 --spp 4 --out fromglb -q");
  ASSERT_EQ(g.status, 0) << g.err;
  const auto from_glb = sirad::test::exr_channels(dir_ / "fromglb.exr");
  for (const auto& [c, values] : imaged) EXPECT_EQ(from_glb.at(c), values) << c;
  write("walk.txt", "# two views\neye 278 273 -800 look 278 273 0 up 0 1 0 fov 39.3\n\neye 100 273 -600 look 278 273 0 up 0 1 0 fov 50\n");
  Outcome w = sirad("image cornell.ply --cameras walk.txt --width 8 --height 8 --spp 1 --out walk -q");
  ASSERT_EQ(w.status, 0) << w.err;
  for (const char* f : {"walk-0001.exr", "walk-0002.exr", "walk-0001.png", "walk-0002.png"}) EXPECT_TRUE(fs::exists(dir_ / f)) << f;
  write("walk.txt", "# a view with no direction\neye 0 0 0 look 0 0 0 up 0 1 0 fov 40\n");
  Outcome bad = sirad("image cornell.ply --cameras walk.txt --out bad");
  EXPECT_EQ(bad.status, 1);
  EXPECT_EQ(bad.err.rfind("sirad: error: walk.txt: line 2:", 0), 0u) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ / "bad.exr"));
  for (const auto& e : fs::directory_iterator(dir_)) fs::remove(e.path());
  write("a-scene", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                     "element face 1\nproperty list uchar int vertex_indices\nproperty float emission_r\nproperty float emission_g\n"
                     "property float emission_b\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2 1 1 1\n");
  expect_error(sirad("image a-scene"), "not a solution");  // (a PLY scene; named so no .ply is taken for an output)
  expect_error(sirad("image nothing.ply"), "nothing.ply");
  expect_error(sirad("image nothing.ply --exposure nan"), "--exposure");
  expect_error(sirad("render cornell --final-gather 4 --flat"), "--flat");
}

// `sirad bake`: the run's outputs and the lightmap's three files, named on stdout with a line of
// figures (the atlas, the samples, the texels' error); the EXR is half-float radiance with the
// error layer; a budget or sample count out of range is one line naming the flag, and texels
// too small for an atlas one line naming it, before any work; `render --lightmap` bakes the same
// way.
TEST_F(Cli, BakeWritesTheLightmapFilesBesideTheRunsOutputs) {
  Outcome r = sirad("bake cornell --patches 300 --bundles 16 --width 32 --height 32 --texels 4096 --texel-samples 4 --out c");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* end : {".exr", ".png", ".ply", ".glb", "-lightmap.exr", "-lightmap.png", "-baked.glb"}) {
    EXPECT_TRUE(fs::exists(dir_ / (std::string("c") + end))) << end;
    EXPECT_NE(r.out.find((dir_ / (std::string("c") + end)).string()), std::string::npos) << end << "\n" << r.out;
  }
  EXPECT_NE(r.out.find("4 samples a texel"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("relative error per texel"), std::string::npos) << r.out;
  Imf::InputFile exr((dir_ / "c-lightmap.exr").string().c_str());
  ASSERT_NE(exr.header().channels().findChannel("error.R"), nullptr);
  EXPECT_EQ(exr.header().channels().findChannel("R")->type, Imf::HALF);
  auto* units = exr.header().findTypedAttribute<Imf::StringAttribute>("sirad.lightmap");
  ASSERT_NE(units, nullptr);
  EXPECT_EQ(units->value(), "radiance");

  for (const char* bad : {"--texels 10", "--texel-samples 1", "--texel-size -1", "--texel-lights 0", "--texel-lights 65"}) {
    Outcome b = sirad(std::string("bake cornell --bundles 4 --out d ") + bad);
    EXPECT_NE(b.status, 0) << bad;
    EXPECT_NE(b.err.find(std::string(bad).substr(0, std::string(bad).find(' '))), std::string::npos) << b.err;
    EXPECT_FALSE(fs::exists(dir_ / "d.exr")) << bad;
  }
  // Texels too small for the largest atlas: refused before the solve, nothing written.
  Outcome small = sirad("bake cornell --bundles 4 --out d --texel-size 0.001");
  EXPECT_NE(small.status, 0);
  EXPECT_NE(small.err.find("atlas"), std::string::npos) << small.err;
  EXPECT_FALSE(fs::exists(dir_ / "d.exr"));
  EXPECT_FALSE(fs::exists(dir_ / "d.ply"));
  Outcome l = sirad("render cornell --patches 300 --bundles 8 --width 32 --height 32 --lightmap --texels 4096 --texel-samples 2 --out e");
  ASSERT_EQ(l.status, 0) << l.err;
  EXPECT_TRUE(fs::exists(dir_ / "e-baked.glb"));
}
