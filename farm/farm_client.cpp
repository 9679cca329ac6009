// sirad: the farm's command-line client (see farm_client.h).
#include "farm/farm_client.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <tuple>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "farm/farm.h"
#include "scene/encoding.h"
#include "scene/scene.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"

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

// The largest answer read from a farm: its list of kMaxJobs jobs is well under it. A farm that
// sends more is cut off while it sends, not held in memory.
constexpr std::size_t kMaxAnswerBytes = std::size_t{64} << 20;

// `req` sent to the farm; the body of a 2xx answer as JSON (its size and nesting bounded); else
// one line saying what the farm said.
json exchange(httplib::Client& c, httplib::Request req, const Endpoint& e, const std::string& what) {
  std::string text;
  bool too_large = false;
  req.content_receiver = [&](const char* data, std::size_t n, uint64_t, uint64_t) {
    if (text.size() + n > kMaxAnswerBytes) {
      too_large = true;
      return false;
    }
    text.append(data, n);
    return true;
  };
  const httplib::Result r = c.send(req);
  if (too_large) fail("{}: the farm at {} answered with more than {} MiB", what, e.url, kMaxAnswerBytes >> 20);
  if (!r) fail("{}: no answer from the farm at {} ({})", what, e.url, httplib::to_string(r.error()));
  json body;
  try {
    body = parse_json_bounded(text, fmt::format("{}: the answer of the farm at {}", what, e.url), kMaxAnswerBytes);
  } catch (const json::exception&) {
    fail("{}: the farm at {} answered {} with no JSON", what, e.url, r->status);
  }
  if (r->status / 100 != 2) fail("{}: {}", what, body.is_object() ? body.value("error", text) : text);
  return body;
}

httplib::Request request(const std::string& method, const std::string& path) {
  httplib::Request req;
  req.method = method;
  req.path = path;
  return req;
}

// A POST of `items` as multipart/form-data (RFC 7578), with a boundary none of them contains.
httplib::Request multipart_post(const std::string& path, const httplib::MultipartFormDataItems& items) {
  static constexpr char kAlphabet[] = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz";
  std::random_device seed;
  std::mt19937_64 random(seed());
  std::string boundary;
  auto in_an_item = [&] {
    return std::any_of(items.begin(), items.end(), [&](const auto& item) { return item.content.find(boundary) != std::string::npos; });
  };
  do {
    boundary = "sirad-";
    for (int k = 0; k < 32; ++k) boundary += kAlphabet[random() % (sizeof kAlphabet - 1)];
  } while (in_an_item());
  httplib::Request req = request("POST", path);
  for (const auto& item : items) {
    req.body += "--" + boundary + "\r\nContent-Disposition: form-data; name=\"" + item.name + "\"";
    if (!item.filename.empty()) req.body += "; filename=\"" + item.filename + "\"";
    req.body += "\r\n";
    if (!item.content_type.empty()) req.body += "Content-Type: " + item.content_type + "\r\n";
    req.body += "\r\n" + item.content + "\r\n";
  }
  req.body += "--" + boundary + "--\r\n";
  req.set_header("Content-Type", "multipart/form-data; boundary=" + boundary);
  return req;
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
    Scene s = load_scene(scene, plan.output.import());
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
  json job = exchange(c, multipart_post("/api/jobs", items), e, "submit");
  std::printf("submitted job %llu (%s) to %s\n", static_cast<unsigned long long>(job.value("id", uint64_t{0})),
              job.value("name", "").c_str(), e.url.c_str());
  return 0;
}

int list_jobs(const FarmAddress& at) {
  const Endpoint e = resolve(at, false);
  httplib::Client c = client(e);
  json body = exchange(c, request("GET", "/api/jobs"), e, "jobs");
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
  if (const uint64_t older = body.value("older", uint64_t{0}); older > 0)
    std::printf("(%llu older jobs not listed)\n", static_cast<unsigned long long>(older));
  return 0;
}

int cancel_job(const FarmAddress& at, uint64_t id) {
  const Endpoint e = resolve(at, true);
  httplib::Client c = client(e);
  json job = exchange(c, request("POST", fmt::format("/api/jobs/{}/cancel", id)), e, fmt::format("cancel {}", id));
  std::printf("job %llu: %s\n", static_cast<unsigned long long>(id),
              job.value("state", "") == "cancelled" ? "cancelled" : "cancelling (it stops at its next checkpoint)");
  return 0;
}

}  // namespace sirad::cli
