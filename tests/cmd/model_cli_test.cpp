// sirad tests: `sirad model` end to end: the paper's model printed for a setup, a sweep and its
// best period, the setup and costs of a measured run, a profile's links charged; bad flags are
// one clear line.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "tests/cli_fixture.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;
using test::Cli;
using test::Outcome;

// `sirad model`: the paper's settings give N = 12 iterations for P = 8 (equation 2: 60 / 4.9),
// a sweep prints one row per value, the last line names the best period, and bad flags are one
// clear line.
class ModelCli : public Cli {};

TEST_F(ModelCli, PrintsTheModelAndRefusesBadFlags) {
  Outcome one = sirad("model");
  ASSERT_EQ(one.status, 0) << one.err;
  EXPECT_EQ(one.out.rfind("processors,exchange_every,fraction,contraction,sigma_ratio", 0), 0u) << one.out;
  EXPECT_NE(one.out.find("\n8,1,1,0.5,1,4.5,0.05,60,12,12,"), std::string::npos) << one.out;
  EXPECT_NE(one.out.find("# best exchange period"), std::string::npos);
  Outcome sweep = sirad("model --sweep processors --max 16 --contraction 0.8");
  ASSERT_EQ(sweep.status, 0) << sweep.err;
  EXPECT_EQ(std::count(sweep.out.begin(), sweep.out.end(), '\n'), 1 + 16 + 1);
  // Fitted on a scene's real bundles: the furnace contracts by its albedo, 0.5 (model_fit_test).
  Outcome fitted = sirad("model --scene furnace --patches 200");
  ASSERT_EQ(fitted.status, 0) << fitted.err;
  EXPECT_NE(fitted.out.find("# fitted on furnace"), std::string::npos) << fitted.out;
  EXPECT_NE(fitted.out.find("contraction a = 0.5000"), std::string::npos) << fitted.out;
  expect_error(sirad("model --scene nothere.obj"), "nothere.obj");
  expect_error(sirad("model --fraction 0"), "--fraction");
  expect_error(sirad("model --contraction 1"), "--contraction");
  expect_error(sirad("model --contraction nan"), "--contraction");
  expect_error(sirad("model --time-to nan"), "--time-to");
  expect_error(sirad("model --sweep everything"), "--sweep");
}

// `sirad model --from-run`: the setup and costs of a run's --status-json. By hand: two nodes
// busy 2 s each for 100 bundles each, idle 0.5 s and 0.3 s over 5 exchanges each, S = 0.5:
// T_i = 4 / 200 = 0.02 s, T_e = 0.8 / (10 x 2 x 0.5) = 0.08 s. Then a real sync run's file
// reads back (P = 2, its I), and a broken file is one clear line naming it.
TEST_F(ModelCli, TakesTheSetupAndCostsOfARun) {
  write("hand.json",
        "{\"bundles_done\": 200, \"bundles\": 200, \"elapsed_s\": 5.0, \"exchanges\": 10, \"exchange_every\": 20, "
        "\"exchange_fraction\": 0.5, \"mode\": \"sync\", \"topology\": \"star\", \"nodes\": ["
        "{\"name\": \"a\", \"state\": \"done\", \"bundles\": 100, \"exchanges\": 5, \"busy_s\": 2.0, \"idle_s\": 0.5},"
        "{\"name\": \"b\", \"state\": \"done\", \"bundles\": 100, \"exchanges\": 5, \"busy_s\": 2.0, \"idle_s\": 0.3}]}");
  Outcome hand = sirad("model --from-run hand.json");
  ASSERT_EQ(hand.status, 0) << hand.err;
  EXPECT_NE(hand.out.find("P = 2, I = 20, S = 0.5 (sync, star), T = 5.000 s, T_i = 0.020000 s"), std::string::npos) << hand.out;
  EXPECT_NE(hand.out.find("T_e = 0.080000 s"), std::string::npos) << hand.out;
  EXPECT_NE(hand.out.find("\n2,20,0.5,"), std::string::npos) << hand.out;

  Outcome run = sirad("render cornell --patches 300 --bundles 120 --nodes 2 --exchange-every 10 --mode sync "
                      "--status-json run.json --width 16 --height 16 -q");
  ASSERT_EQ(run.status, 0) << run.err;
  Outcome fitted = sirad("model --from-run run.json --time 60");
  ASSERT_EQ(fitted.status, 0) << fitted.err;
  EXPECT_NE(fitted.out.find("P = 2, I = 10, S = 1 (sync, star), T = 60.000 s"), std::string::npos) << fitted.out;
  for (const char* ext : {".exr", ".png", ".ply"}) fs::remove(dir_ / (std::string("cornell") + ext));

  write("broken.json", "{\"bundles_done\": 1, \"nodes\": []}");
  expect_error(sirad("model --from-run broken.json"), "broken.json");
  expect_error(sirad("model --from-run missing.json"), "missing.json");
}

// `sirad model --profile`: T_e from the links. By hand, 1,000 patches (24,000 bytes, 192,000
// bits) at P = 4: a node's link 100 Mbit/s both ways and 1 ms: e = 2 x 1.92 ms + 2 ms = 5.84 ms;
// the coordinator's 1000 Mbit/s in, 500 out, 0.5 ms: c = 0.384 ms + 0.5 ms = 0.884 ms per node,
// so T_e = max(e / P, c) = max(1.46, 0.884) ms = 1.46 ms; without the coordinator, the same e / P.
// And the flags it conflicts with are refused, never ignored.
TEST_F(ModelCli, ChargesTheLinksOfAProfile) {
  write("p.yaml", "defaults: {bandwidth_mbit: 100, latency_ms: 1}\ncoordinator: {up_mbit: 1000, down_mbit: 500, latency_ms: 0.5}\n");
  Outcome hub = sirad("model --processors 4 --profile p.yaml --state-patches 1000");
  ASSERT_EQ(hub.status, 0) << hub.err;
  EXPECT_NE(hub.out.find("the nodes' links 0.005840 s each (side by side), the coordinator's 0.000884 s per node (in turn); "
                         "T_e = 0.001460 s"),
            std::string::npos)
      << hub.out;
  Outcome many = sirad("model --processors 64 --profile p.yaml --state-patches 1000");
  ASSERT_EQ(many.status, 0) << many.err;
  EXPECT_NE(many.out.find("T_e = 0.000884 s"), std::string::npos) << many.out;  // 5.84 / 64 < 0.884
  write("q.yaml", "defaults: {bandwidth_mbit: 100, latency_ms: 1}\n");
  Outcome nodes_only = sirad("model --processors 4 --profile q.yaml --state-patches 1000");
  ASSERT_EQ(nodes_only.status, 0) << nodes_only.err;
  EXPECT_NE(nodes_only.out.find("not modelled; T_e = 0.001460 s"), std::string::npos) << nodes_only.out;
  expect_error(sirad("model --profile p.yaml"), "--state-patches");
  expect_error(sirad("model --profile p.yaml --state-patches 10 --t-exchange 1"), "--t-exchange");
  expect_error(sirad("model --profile p.yaml --state-patches 10 --sweep processors"), "cannot sweep");
  expect_error(sirad("model --state-patches 10"), "only with --profile");
  expect_error(sirad("model --profile missing.yaml --state-patches 10"), "missing.yaml");
}

}  // namespace
}  // namespace sirad
