// sirad: the embedded cluster driver (see embedded.h).
#include "cli/embedded.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <zmq.hpp>

#include "coordinator/coordinator.h"
#include "node/node.h"
#include "util/error.h"

namespace sirad::embedded {

Outcome run(cluster::RunConfig config, const PatchMesh& mesh, const Options& o) {
  using Clock = std::chrono::steady_clock;
  auto seconds_since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  const auto t0 = Clock::now();
  Outcome out;
  {
    zmq::context_t context;
    zmq::socket_t router(context, zmq::socket_type::router);
    router.set(zmq::sockopt::linger, 0);
    router.bind(o.endpoint);
    const std::string endpoint = router.get(zmq::sockopt::last_endpoint);
    std::atomic<bool> stop{false}, failed{false};
    std::vector<std::string> errors(static_cast<std::size_t>(o.nodes));
    const int gather_threads =
        o.gather_threads > 0 ? o.gather_threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / std::max(1, o.nodes));
    std::vector<std::jthread> threads;  // joined however this block ends (declared after what they use)
    for (int i = 0; i < o.nodes; ++i)
      threads.emplace_back([&, i] {
        try {
          node::serve(context, endpoint,
                      {.name = fmt::format("{}{}", o.name_prefix, i),
                       .device = o.device,
                       .transfer = o.transfer,
                       .stop = &stop,
                       .poll_ms = o.poll_ms,
                       .gather_threads = gather_threads});
        } catch (const std::exception& e) {
          errors[static_cast<std::size_t>(i)] = e.what();
          failed = true;
        }
      });
    struct StopOnExit {  // destroyed before `threads`: however this ends, the nodes are told first
      std::atomic<bool>& stop;
      ~StopOnExit() { stop = true; }
    } stop_on_exit{stop};
    config.strict = true;
    config.abort = &failed;
    try {
      out.result = cluster::coordinate(router, config, mesh);
    } catch (...) {
      stop = true;
      for (auto& t : threads) t.join();
      for (int i = 0; i < o.nodes; ++i)
        if (!errors[static_cast<std::size_t>(i)].empty())
          fail("{}{}: {}", o.name_prefix, i, errors[static_cast<std::size_t>(i)]);
      throw;
    }
    out.coordinate_s = seconds_since(t0);
    stop = true;  // the node threads leave within a poll interval
    if (o.on_done) o.on_done(out.result);
  }
  out.total_s = seconds_since(t0);
  return out;
}

}  // namespace sirad::embedded
