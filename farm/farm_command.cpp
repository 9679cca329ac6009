// sirad: `sirad-coordinator --serve DIR` (see farm_command.h).
#include "farm/farm_command.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "cli/stop_signals.h"
#include "coordinator/listener.h"
#include "farm/farm.h"
#include "farm/farm_http.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/log.h"

namespace sirad::cli {

int serve_farm_command(const CoordinatorArgs& a, const std::string& dir, const std::string& http, const std::string& token_file) {
  const auto [keys, allow] = coordinator::server_keys(a.listen, a.curve_secret, a.allow_file, a.insecure);
  const auto colon = http.rfind(':');
  int port = -1;
  if (colon != std::string::npos && colon > 0 && colon + 1 < http.size() && colon + 6 >= http.size() &&
      std::all_of(http.begin() + static_cast<long>(colon) + 1, http.end(), [](char c) { return c >= '0' && c <= '9'; }))
    port = std::stoi(http.substr(colon + 1));
  if (port < 0 || port > 65535) fail("--http {}: expected HOST:PORT (e.g. 127.0.0.1:8080)", http);
  const std::string host = http.substr(0, colon);
  cluster::JobStore store(dir, unix_now(), !a.check_config);  // a check changes nothing of a farm that may be running
  const std::string token = farm_token(token_file.empty() ? (std::filesystem::path(dir) / "token").string() : token_file);
  if (a.check_config) {
    std::printf("sirad-coordinator: config ok: farm %s, %zu jobs, %s\n", dir.c_str(), store.list().size(), http.c_str());
    return 0;
  }
  zmq::context_t context;
  coordinator::Listener listener(context, a.listen, keys, allow, kFarmMaxPatches, a.insecure, a.endpoint_file, fmt::format("farm {}", dir));
  FarmView view;
  FarmHttp server(store, view, token);
  const int bound = server.start(host, port);
  const std::string url = fmt::format("http://{}:{}", host, bound);
  write_file_atomic((std::filesystem::path(dir) / "http").string(), url);
  logging::write(logging::Level::info, "sirad-coordinator", fmt::format("farm {}: web page and API on {}", dir, url),
                 {{"event", "http"}, {"url", url}});
  FarmOptions options;
  options.process.heartbeat_ms = static_cast<uint32_t>(a.heartbeat_ms);
  options.process.liveness = static_cast<uint32_t>(a.liveness);
  options.process.checkpoint_every_s = a.checkpoint_every;
  options.stop = &stop_on_signals();
  options.peer_bytes = &*listener.bytes;
  serve_farm(context, listener.router, store, options, view);
  server.stop();
  logging::write(logging::Level::info, "sirad-coordinator", "farm stopped", {{"event", "stopped"}});
  return 0;
}

}  // namespace sirad::cli
