// sirad: `sirad-coordinator --serve DIR`: the farm (farm.h) on one socket, its HTTP API and page
// beside it (farm_http.h), until SIGTERM or SIGINT.
#pragma once
#include <string>

#include "cli/coordinator_command.h"

namespace sirad::cli {

// Serves the farm of folder `dir` (made if need be) with its web page and API on `http`
// (HOST:PORT) behind the token of `token_file` (default: DIR/token), on the socket and with the
// security, liveness and checkpoint period `a` gives (its run and output flags are the jobs').
// With a.check_config: checks the folder, token and flags and returns. The exit status.
int serve_farm_command(const CoordinatorArgs& a, const std::string& dir, const std::string& http, const std::string& token_file);

}  // namespace sirad::cli
