// The paper's cost and error model (model/model.h): its closed forms against its recurrences,
// small cases by hand, and the optimum exchange period against a brute-force search.
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "model/model.h"
#include "util/error.h"

namespace sirad::model {
namespace {

// (1) and (2): the paper's figures (T = 60 s, T_i = 4.5 s, T_e = 0.05 s, P = 8, S = 1, I = 1)
// give N = 60 / 4.9 = 12.2 -> 12 iterations; the budget of N iterations inverts exactly.
TEST(Model, TimeBudget) {
  Costs paper;
  model::Setup s{8, 1, 1.0};
  EXPECT_EQ(iterations_in(60.0, s, paper), 12u);
  EXPECT_DOUBLE_EQ(total_time(12, s, paper), 12 * 4.5 + 12 * 8 * 0.05);
  for (model::Setup q : {model::Setup{1, 1, 1.0}, model::Setup{8, 4, 0.5}, model::Setup{16, 0, 1.0}, model::Setup{3, 7, 0.125}})
    for (uint64_t n : {1u, 13u, 1000u}) EXPECT_EQ(iterations_in(total_time(n, q, paper), q, paper), n);
  model::Setup never{8, 0, 1.0};
  EXPECT_DOUBLE_EQ(total_time(10, never, paper), 45.0);  // I = 0: no exchange costs
}

// Sample numbers by hand. One processor, independent steps: s_n(k) = C(n, k), the paths of
// length k among n steps (n = 3: 3, 3, 1). Two processors, a combined step every step (I = 1,
// S = 1): step 1 gives s(1) = 2; step 2 advances each path on both processors,
// s(2) = P S s(1) = 4, and adds 2 new ones: (4, 4).
TEST(Model, SampleNumbersSmallCases) {
  auto ls = log_sample_numbers(3, {1, 0, 1.0});
  ASSERT_EQ(ls.size(), 3u);
  EXPECT_NEAR(std::exp(ls[0]), 3.0, 1e-12);
  EXPECT_NEAR(std::exp(ls[1]), 3.0, 1e-12);
  EXPECT_NEAR(std::exp(ls[2]), 1.0, 1e-12);
  auto two = log_sample_numbers(2, {2, 1, 1.0});
  EXPECT_NEAR(std::exp(two[0]), 4.0, 1e-12);
  EXPECT_NEAR(std::exp(two[1]), 4.0, 1e-12);
  // Independent steps on P processors: each keeps its own paths, s(k) = P C(n, k).
  auto four = log_sample_numbers(5, {4, 0, 1.0});
  EXPECT_NEAR(std::exp(four[1]), 4.0 * 10.0, 1e-9);
  // Truncated to the first bounces: the same values for them.
  auto cut = log_sample_numbers(5, {4, 0, 1.0}, 2);
  ASSERT_EQ(cut.size(), 2u);
  EXPECT_DOUBLE_EQ(cut[1], four[1]);
}

// Section 2's error: with a = 0 only first bounces count and there is no bias, so one sample
// gives 3 sigma_1 / C; with a = 0.5, N = 1 (one path of length 1 from one processor) the bias
// of the missing bounces is a^2 = 0.25 and the deviation 3 (1 - a) sigma_1 / C.
TEST(Model, RelativeErrorSmallCases) {
  std::vector<double> one = {0.0};  // ln s(1) = ln 1
  EXPECT_NEAR(relative_error(one, {0.0, 1.0}), 3.0, 1e-12);
  EXPECT_NEAR(relative_error(one, {0.5, 2.0}), 0.25 + 3.0 * 0.5 * 2.0, 1e-12);
  // More iterations: the error falls (1 / sqrt for the first bounce's share).
  Costs paper;
  Scene scene{0.5, 1.0};
  EXPECT_LT(predict(120.0, {8, 1, 1.0}, paper, scene).relative_error, predict(60.0, {8, 1, 1.0}, paper, scene).relative_error);
}

// Section 5's closed form A (B^K - 1) / (B - 1) equals the effective sample number of the
// recurrences, for whole phases, over processors, periods, fractions and contractions
// (including a = 0, where A = P I and B = 1).
TEST(Model, ClosedFormEqualsRecurrence) {
  for (uint32_t p : {1u, 2u, 8u})
    for (uint64_t i : {1u, 3u, 7u})
      for (double s : {1.0, 0.5, 0.125})
        for (double a : {0.0, 0.3, 0.8, 0.95})
          for (uint64_t k : {1u, 2u, 5u}) {
            model::Setup setup{p, i, s};
            double rec = log_effective_samples(log_sample_numbers(k * i, setup), a);
            double closed = log_effective_samples_closed(k, setup, a);
            EXPECT_NEAR(closed, rec, 1e-9 * std::max(1.0, std::fabs(rec)))
                << "P " << p << " I " << i << " S " << s << " a " << a << " K " << k;
          }
}

// P = 1 is a single stochastic iteration: exchanging with nobody changes nothing, whatever I,
// and E after N steps is ((1 + a^2)^N - 1) / a^2.
TEST(Model, OneProcessorIsOneStochasticIteration) {
  const double a = 0.7;
  auto never = log_sample_numbers(20, {1, 0, 1.0});
  for (uint64_t i : {1u, 4u, 20u}) {
    auto with = log_sample_numbers(20, {1, i, 1.0});
    for (std::size_t k = 0; k < never.size(); ++k) EXPECT_NEAR(with[k], never[k], 1e-12) << "I " << i << " k " << k;
  }
  EXPECT_NEAR(std::exp(log_effective_samples(never, a)), (std::pow(1 + a * a, 20) - 1) / (a * a), 1e-6);
}

// The best exchange period for the effective sample number: the golden-section search on the
// closed form finds the same whole I as trying every I, across contractions, processor counts,
// exchange costs and budgets (optima at I = 1 and inside the range: 2, 6 and 11 among these).
TEST(Model, BestPeriodMatchesBruteForce) {
  int checked = 0, interior = 0;
  for (double a : {0.2, 0.5, 0.8, 0.95})
    for (uint32_t p : {2u, 8u, 32u})
      for (double te : {0.0005, 0.05, 0.5})
        for (double time : {60.0, 600.0}) {
          Costs c{4.5, te};
          model::Setup s{p, 1, 1.0};
          uint64_t fast = best_period(time, s, c, a, 200), slow = brute_force_period(time, s, c, a, 200);
          EXPECT_EQ(fast, slow) << "a " << a << " P " << p << " T_e " << te << " T " << time;
          ++checked;
          interior += slow > 1;
        }
  EXPECT_EQ(checked, 72);
  EXPECT_GE(interior, 3) << "the cases no longer reach optima away from I = 1";
}

TEST(Model, BadInputIsNamed) {
  auto message = [](auto f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message([] { check(model::Setup{0, 1, 1.0}); }).find("processors"), std::string::npos);
  EXPECT_NE(message([] { check(model::Setup{2, 1, 1.5}); }).find("fraction"), std::string::npos);
  EXPECT_NE(message([] { check(Scene{1.0, 1.0}); }).find("contraction"), std::string::npos);
  EXPECT_NE(message([] { check(Scene{0.5, 0.0}); }).find("sigma"), std::string::npos);
  EXPECT_NE(message([] { check(Costs{0.0, 0.1}); }).find("T_i"), std::string::npos);
  EXPECT_NE(message([] { iterations_in(NAN, model::Setup{}, Costs{}); }).find("time"), std::string::npos);
}

}  // namespace
}  // namespace sirad::model

namespace sirad::model {
namespace {

// Too little time for one iteration: nothing is estimated, the error is unbounded.
TEST(Model, NoIterationNoEstimate) {
  Prediction p = predict(1.0, model::Setup{8, 1, 1.0}, Costs{4.5, 0.05}, Scene{0.5, 1.0});
  EXPECT_EQ(p.iterations, 0u);
  EXPECT_TRUE(std::isinf(p.relative_error));
  EXPECT_TRUE(std::isinf(p.log_effective) && p.log_effective < 0);
}

}  // namespace
}  // namespace sirad::model

namespace sirad::model {
namespace {

// choose_exchange: up to 16 every period is a candidate, so it must equal the brute-force
// minimum of the predicted error over I = 1..max and S in {1, 1/2, 1/4, 1/8}; and exchanging
// costs more when T_e grows, so its period never shortens as T_e rises.
TEST(ModelChoice, ChooseExchangeIsTheBruteForceMinimum) {
  for (double a : {0.2, 0.5, 0.8}) {
    for (double te : {0.0, 0.05, 0.5, 5.0}) {
      Costs costs{1.0, te};
      Scene scene{a, 2.0};
      ExchangeChoice c = choose_exchange(60.0, 8, costs, scene, 16);
      double best = std::numeric_limits<double>::infinity();
      for (double s : {1.0, 0.5, 0.25, 0.125})
        for (uint64_t i = 1; i <= 16; ++i) best = std::min(best, predict(60.0, {8, i, s}, costs, scene).relative_error);
      EXPECT_NEAR(c.prediction.relative_error, best, 1e-9 * best) << "a " << a << ", T_e " << te;
      EXPECT_DOUBLE_EQ(c.prediction.relative_error, predict(60.0, {8, c.period, c.fraction}, costs, scene).relative_error);
    }
    uint64_t last = 0;
    for (double te : {0.0, 0.05, 0.5, 5.0}) {
      ExchangeChoice c = choose_exchange(60.0, 8, {1.0, te}, {a, 2.0}, 16);
      EXPECT_GE(c.period * 8 / c.fraction, last * 1.0) << "a " << a << ", T_e " << te;  // exchanges per bundle fall
      last = static_cast<uint64_t>(c.period * 8 / c.fraction);
    }
  }
}

}  // namespace
}  // namespace sirad::model

namespace sirad::model {
namespace {

// time_to_error: the predicted error at that time is at or below the target, and one iteration
// less (on the same setup) is above it; an unreachable target is inf.
TEST(ModelChoice, TimeToErrorIsTheFirstTimeTheErrorIsReached) {
  for (double a : {0.3, 0.8})
    for (uint32_t p : {1u, 4u, 16u}) {
      model::Setup s{p, 1, 1.0};
      Costs c{4.5, 0.05};
      Scene sc{a, 1.0};
      double t = time_to_error(0.1, s, c, sc);
      ASSERT_TRUE(std::isfinite(t));
      uint64_t n = iterations_in(t * (1 + 1e-12), s, c);
      EXPECT_LE(predict(t * (1 + 1e-12), s, c, sc).relative_error, 0.1) << a << " " << p;
      EXPECT_GT(predict(total_time(n - 1, s, c), s, c, sc).relative_error, 0.1) << a << " " << p;
    }
  EXPECT_TRUE(std::isinf(time_to_error(0.1, {1, 1, 1.0}, {4.5, 0.05}, {0.5, 1e6}, 1000)));
}

}  // namespace
}  // namespace sirad::model

namespace sirad::model {
namespace {

// The combined step's factor 1 + (P - 1) S (model.h: eq. 6's P S would make a small exchange
// lose paths): P at S = 1; as S falls to 0 the sample numbers fall to the independent run's,
// never below them.
TEST(ModelChoice, ExchangingAFractionNeverLosesPaths) {
  EXPECT_DOUBLE_EQ(combined_factor(8, 1.0), 8.0);
  auto independent = log_sample_numbers(20, {8, 0, 1.0});
  for (double s : {1.0, 0.5, 0.1, 0.01, 1e-6}) {
    auto ls = log_sample_numbers(20, {8, 1, s});
    for (std::size_t k = 0; k < ls.size(); ++k) EXPECT_GE(ls[k], independent[k] - 1e-12) << "S " << s << ", k " << k;
  }
  auto tiny = log_sample_numbers(20, {8, 1, 1e-9});
  for (std::size_t k = 0; k < tiny.size(); ++k) EXPECT_NEAR(tiny[k], independent[k], 1e-6) << k;
}

}  // namespace
}  // namespace sirad::model
