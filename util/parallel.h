// sirad: the one way work is spread over a machine's cores (the reference solver, the final
// gather, the ray scene's overlap search). Indices are handed out in ranges from one counter, so
// a result that depends only on each index's own work is the same on any number of threads.
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace sirad {

// The threads to use when `requested` of them are asked for: `requested`, or every core for 0.
inline unsigned worker_threads(int requested) {
  return requested > 0 ? static_cast<unsigned>(requested) : std::max(1u, std::thread::hardware_concurrency());
}

// Calls body(begin, end, worker) for ranges [begin, end) that cover [0, count) once, each of at
// most `grain` indices, on min(threads, ranges) threads: the caller's (worker 0) and threads of
// its own, each with its worker number in [0, threads). Returns when every range is done. If a
// body throws, no thread starts another range, and the exception of the lowest worker that threw
// is rethrown here once every thread has stopped (an error in a worker is the caller's error, as
// it would be on one thread, never the end of the process).
template <class Body>
void parallel_for(std::size_t count, std::size_t grain, unsigned threads, Body&& body) {
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t ranges = count / grain + (count % grain != 0);
  threads = static_cast<unsigned>(std::clamp<std::size_t>(ranges, 1, std::max(threads, 1u)));
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::vector<std::exception_ptr> errors(threads);
  auto work = [&](unsigned worker) {
    try {
      for (std::size_t begin; !failed.load(std::memory_order_relaxed) && (begin = next.fetch_add(grain)) < count;)
        body(begin, std::min(count, begin + grain), worker);
    } catch (...) {
      errors[worker] = std::current_exception();
      failed.store(true);
    }
  };
  {
    // Joined at the end of this scope, also when starting a thread throws (the threads started
    // then do all the work).
    std::vector<std::jthread> pool;
    pool.reserve(threads - 1);
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t);
    work(0);
  }
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace sirad
