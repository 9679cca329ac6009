// sirad: the farm's command-line client (see farm_client.h).
#include "cmd/farm_client.h"

#include <cstdlib>
#include <filesystem>
#include <tuple>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "cmd/farm.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/scene.h"
#include "core/scene_io.h"

namespace sirad::cli {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Endpoint {
  std::string url, token;
};

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

// The URL, and the token when `need_token`.
Endpoint resolve(const FarmAddress& at, bool need_token) {
  if (at.farm.empty()) fail("--farm: give the farm's URL (http://HOST:PORT) or its folder");
  Endpoint e;
  const bool folder = at.farm.rfind("http://", 0) != 0;
  if (folder) {
    if (!fs::is_directory(at.farm)) fail("--farm {}: neither http://HOST:PORT nor a farm's folder", at.farm);
    e.url = trimmed(read_file_whole((fs::path(at.farm) / "http").string(), "farm's address", 4096));
  } else {
    e.url = at.farm;
  }
  if (!need_token) return e;
  if (!at.token_file.empty()) e.token = trimmed(read_file_whole(at.token_file, "farm token", 4096));
  else if (const char* env = std::getenv("SIRAD_FARM_TOKEN"); env && *env) e.token = env;
  else if (folder) e.token = trimmed(read_file_whole((fs::path(at.farm) / "token").string(), "farm token", 4096));
  else fail("submitting and cancelling need the farm's token: --token-file FILE (or SIRAD_FARM_TOKEN)");
  return e;
}

httplib::Client client(const Endpoint& e) {
  httplib::Client c(e.url);
  c.set_connection_timeout(10);
  c.set_read_timeout(300);
  c.set_write_timeout(300);
  if (!e.token.empty()) c.set_bearer_token_auth(e.token);
  return c;
}

// The body of a 2xx answer as JSON; else one line saying what the farm said.
json answer(const httplib::Result& r, const Endpoint& e, const std::string& what) {
  if (!r) fail("{}: no answer from the farm at {} ({})", what, e.url, httplib::to_string(r.error()));
  json body;
  try {
    body = json::parse(r->body);
  } catch (const json::exception&) {
    fail("{}: the farm at {} answered {} with no JSON", what, e.url, r->status);
  }
  if (r->status / 100 != 2) fail("{}: {}", what, body.is_object() ? body.value("error", r->body) : r->body);
  return body;
}

}  // namespace

int submit_job(const FarmAddress& at, const std::string& scene, const std::vector<std::string>& args, const std::string& name,
               int priority) {
  JobPlan plan = plan_job(args);  // refused here, before any upload
  const Endpoint e = resolve(at, true);
  const std::string job_name = name.empty() ? fs::path(scene).stem().string() : name;
  json spec = {{"name", job_name}, {"args", args}, {"priority", priority}};
  httplib::MultipartFormDataItems items;
  if (is_builtin_scene(scene)) {
    spec["scene"] = scene;
  } else {
    Scene s = load_scene(scene, {.skip_degenerate = plan.output.skip_degenerate, .two_sided = plan.output.two_sided});
    // The uploaded scene carries no camera aspect: the image size the scene's camera gives is
    // settled here and sent as flags.
    OutputFlags output = plan.output;
    settle_image_size(output, s);
    for (const auto& [flag, given, settled] : {std::tuple{"--width", plan.output.width, output.width},
                                               std::tuple{"--height", plan.output.height, output.height}})
      if (given == 0) {
        spec["args"].push_back(flag);
        spec["args"].push_back(std::to_string(settled));
      }
    items.push_back({"scene_data", encode_scene(s), "scene.bin", "application/octet-stream"});
  }
  items.push_back({"job", spec.dump(), "job.json", "application/json"});
  httplib::Client c = client(e);
  json job = answer(c.Post("/api/jobs", items), e, "submit");
  std::printf("submitted job %llu (%s) to %s\n", static_cast<unsigned long long>(job.value("id", uint64_t{0})),
              job.value("name", "").c_str(), e.url.c_str());
  return 0;
}

int list_jobs(const FarmAddress& at) {
  const Endpoint e = resolve(at, false);
  httplib::Client c = client(e);
  json body = answer(c.Get("/api/jobs"), e, "jobs");
  std::printf("%-6s %-10s %8s  %-24s %s\n", "id", "state", "priority", "name", "progress");
  for (const json& j : body.value("jobs", json::array())) {
    std::string progress;
    if (j.contains("bundles_done"))
      progress = fmt::format("{}/{} bundles, error {:.3g}", j.value("bundles_done", uint64_t{0}), j.value("bundles", uint64_t{0}),
                             j.value("error_estimate", -1.0));
    else if (!j.value("error", "").empty())
      progress = j.value("error", "");
    std::printf("%-6llu %-10s %8d  %-24s %s\n", static_cast<unsigned long long>(j.value("id", uint64_t{0})),
                j.value("state", "").c_str(), j.value("priority", 0), j.value("name", "").c_str(), progress.c_str());
  }
  return 0;
}

int cancel_job(const FarmAddress& at, uint64_t id) {
  const Endpoint e = resolve(at, true);
  httplib::Client c = client(e);
  json job = answer(c.Post(fmt::format("/api/jobs/{}/cancel", id)), e, fmt::format("cancel {}", id));
  std::printf("job %llu: %s\n", static_cast<unsigned long long>(id),
              job.value("state", "") == "cancelled" ? "cancelled" : "cancelling (it stops at its next checkpoint)");
  return 0;
}

}  // namespace sirad::cli
