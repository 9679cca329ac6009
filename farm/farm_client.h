// sirad: `sirad submit`, `sirad jobs` and `sirad cancel`: a farm's HTTP API (farm/farm_http.h)
// from the command line.
#pragma once
#include <string>
#include <vector>

namespace sirad::cli {

// Where a farm is and how to prove the right to change it. `farm`: its URL (http://HOST:PORT)
// or its folder on this machine (then its `http` file gives the URL and its `token` file the
// token). The token: `token_file`, else SIRAD_FARM_TOKEN, else the folder's.
struct FarmAddress {
  std::string farm, token_file;
};

// Submits SCENE (a built-in name is sent by name; a file is read here and sent encoded, as the
// nodes get it) with `args` (run and output flags, checked here first); prints the job's id.
int submit_job(const FarmAddress& at, const std::string& scene, const std::vector<std::string>& args, const std::string& name,
               int priority);
// Prints the farm's jobs, one line each: id, state, priority, name, progress, error.
int list_jobs(const FarmAddress& at);
int cancel_job(const FarmAddress& at, uint64_t id);

}  // namespace sirad::cli
