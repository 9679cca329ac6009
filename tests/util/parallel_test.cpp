// sirad tests: work spread over threads (util/parallel.h): every index once, whatever the
// threads and the grain, and an exception in any worker comes back to the caller.
#include "util/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstddef>
#include <stdexcept>
#include <vector>

#include "util/error.h"

namespace sirad {
namespace {

TEST(ParallelFor, CoversEveryIndexOnceForAnyThreadsAndGrain) {
  for (unsigned threads : {1u, 2u, 3u, 8u})
    for (std::size_t grain : {std::size_t{0}, std::size_t{1}, std::size_t{7}, std::size_t{1000}})
      for (std::size_t count : {std::size_t{0}, std::size_t{1}, std::size_t{999}}) {
        std::vector<std::atomic<int>> seen(count);
        std::atomic<unsigned> most_worker{0};
        parallel_for(count, grain, threads, [&](std::size_t begin, std::size_t end, unsigned worker) {
          EXPECT_LT(begin, end);
          EXPECT_LE(end - begin, std::max<std::size_t>(grain, 1));
          for (std::size_t i = begin; i < end; ++i) seen[i]++;
          for (unsigned m = most_worker.load(); worker > m && !most_worker.compare_exchange_weak(m, worker);) {}
        });
        for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(seen[i].load(), 1) << threads << " threads, grain " << grain << ", index " << i;
        EXPECT_LT(most_worker.load(), threads);
      }
}

// The caller's worker waits (for the event, not for a time) until another worker has thrown, so
// the exception is born on a thread of parallel_for's own: it reaches the caller instead of
// ending the process.
TEST(ParallelFor, AnExceptionInAnotherThreadReachesTheCaller) {
  std::atomic<bool> thrown{false};
  auto body = [&](std::size_t, std::size_t, unsigned worker) {
    if (worker == 0) {
      while (!thrown.load()) thrown.wait(false);
      return;
    }
    thrown.store(true);
    thrown.notify_all();
    fail("worker {} failed", worker);
  };
  try {
    parallel_for(2, 1, 2, body);
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "worker 1 failed");
  }
}

// After a throw no range starts: of a million ranges on one thread, the one that threw is the last.
TEST(ParallelFor, NoRangeStartsAfterAThrow) {
  std::size_t calls = 0;
  EXPECT_THROW(parallel_for(1000000, 1, 1,
                            [&](std::size_t begin, std::size_t, unsigned) {
                              ++calls;
                              if (begin == 10) throw std::runtime_error("stop");
                            }),
               std::runtime_error);
  EXPECT_EQ(calls, 11u);
}

}  // namespace
}  // namespace sirad
