// sirad: the farm's HTTP API and web page (see farm_http.h).
#include "farm/farm_http.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <random>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "farm/view_server.h"
#include "scene/encoding.h"
#include "scene/scene.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/json_bounded.h"
#include "util/log.h"
#include "util/resources.h"

namespace sirad::cli {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The largest request body: a scene as nodes receive it is at most this (decode_scene's bound).
constexpr std::size_t kMaxBody = std::size_t{1} << 31;

// GET /api/jobs answers this many jobs unless asked (`limit`), at most kMaxJobsPage: the page
// polls it every second.
constexpr uint64_t kJobsPage = 200, kMaxJobsPage = 1000;

// The files a job's folder may hand out, by name (no path from a request reaches the disk).
std::vector<std::string> job_files(const cluster::Job& j, const std::string& folder) {
  std::vector<std::string> out;
  for (const std::string& f : {j.name + ".exr", j.name + ".png", j.name + ".ply", j.name + ".glb", std::string("status.json"),
                               std::string("preview.png"), std::string("preview.glb"), std::string("summary.txt"),
                               std::string("ledger.csv")})
    if (fs::is_regular_file(fs::path(folder) / f)) out.push_back(f);
  return out;
}

// The glb the 3D view shows of a job: its result once written, else the running job's preview.
std::optional<fs::path> job_glb(const cluster::Job& j, const std::string& folder) {
  for (const fs::path& f : {fs::path(folder) / (j.name + ".glb"), fs::path(folder) / "preview.glb"})
    if (fs::is_regular_file(f)) return f;
  return std::nullopt;
}

json job_object(const cluster::Job& j) {
  json o = {{"id", j.id},           {"name", j.name},         {"scene", j.scene.empty() ? "(uploaded)" : j.scene},
            {"args", j.args},       {"priority", j.priority}, {"state", j.state},
            {"submitted", j.submitted}, {"started", j.started}, {"finished", j.finished},
            {"error", j.error},     {"runs", j.runs}};
  if (j.run) {  // the run it was planned to, every setting spelled out (the table's text)
    json settings = json::object();
    for (const auto& [flag, text] : cluster::settings_text(j.run->settings)) settings[flag] = text;
    o["settings"] = std::move(settings);
  }
  return o;
}

void reply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void refuse(httplib::Response& res, int status, const std::string& why) { reply(res, status, {{"error", why}}); }

// Streams `path` in pieces of 1 MiB: a download holds no more than that in memory.
void send_file(httplib::Response& res, const fs::path& path, const char* type) {
  auto file = std::make_shared<std::ifstream>(path, std::ios::binary);
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (!*file || ec) return refuse(res, 404, "no such file of this job");
  res.set_content_provider(static_cast<std::size_t>(size), type, [file](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
    std::vector<char> piece(std::min<std::size_t>(length, std::size_t{1} << 20));
    file->seekg(static_cast<std::streamoff>(offset));
    file->read(piece.data(), static_cast<std::streamsize>(piece.size()));
    if (file->gcount() <= 0) return false;
    return sink.write(piece.data(), static_cast<std::size_t>(file->gcount()));
  });
}

// Compares in time independent of where the strings differ.
bool same(const std::string& a, const std::string& b) {
  unsigned diff = a.size() != b.size();
  for (std::size_t i = 0; i < std::max(a.size(), b.size()); ++i)
    diff |= static_cast<unsigned char>(i < a.size() ? a[i] : 0) ^ static_cast<unsigned char>(i < b.size() ? b[i] : 0);
  return diff == 0;
}

}  // namespace

std::string farm_token(const std::string& path) {
  if (!fs::exists(path)) {
    std::random_device rd;
    std::string token;
    for (int i = 0; i < 8; ++i) token += fmt::format("{:08x}", rd());
    AtomicFile f(path);
    if (::fchmod(fileno(f.stream()), 0600) != 0) f.fail_errno(errno);
    f.write(token.data(), token.size());
    f.commit();
    return token;
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) fail("{}: the farm token is not a file", path);
  if (st.st_mode & 077) fail("{}: the farm token may be read by others (mode {:o}): chmod 600 it", path, st.st_mode & 0777);
  std::string token = read_file_whole(path, "farm token", 4096);
  while (!token.empty() && (token.back() == '\n' || token.back() == '\r' || token.back() == ' ')) token.pop_back();
  if (token.size() < 16 || token.size() > 256 ||
      !std::all_of(token.begin(), token.end(), [](char c) { return c > ' ' && c < 127; }))
    fail("{}: a farm token is 16 to 256 printable characters", path);
  return token;
}

FarmHttp::FarmHttp(cluster::JobStore& store, FarmView& view, std::string token)
    : store_(store), view_(view), token_(std::move(token)), server_(std::make_unique<httplib::Server>()) {
  httplib::Server& s = *server_;
  s.set_payload_max_length(kMaxBody);
  // Everything but reading needs the token, checked before the request's body is read (a body
  // may be 2 GiB: only the token's holder makes the farm hold one).
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (req.method == "GET" || req.method == "HEAD") return httplib::Server::HandlerResponse::Unhandled;
    const std::string h = req.get_header_value("Authorization");
    if (h.rfind("Bearer ", 0) == 0 && same(h.substr(7), token_)) return httplib::Server::HandlerResponse::Unhandled;
    refuse(res, 401, "this needs the farm's token (Authorization: Bearer TOKEN)");
    return httplib::Server::HandlerResponse::Handled;
  });
  auto job_of = [this](const httplib::Request& req, httplib::Response& res) -> std::optional<cluster::Job> {
    const std::string id = req.matches[1];
    std::optional<cluster::Job> j;
    if (id.size() <= 12) j = store_.get(std::stoull(id));
    if (!j) refuse(res, 404, fmt::format("no job {}", id.substr(0, 20)));
    return j;
  };
  s.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_header("Content-Security-Policy",
                   "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src 'self'; connect-src 'self'; "
                   "frame-src 'self'");
    res.set_content(std::string(resource("farm/farm_page.html")), "text/html; charset=utf-8");
  });
  // A page of the queue: the `limit` jobs (default kJobsPage) of the highest ids below `before`
  // (default: all), in id order, with the count of older ones and of all.
  s.Get("/api/jobs", [this](const httplib::Request& req, httplib::Response& res) {
    auto number = [&](const char* name, uint64_t otherwise, uint64_t most) -> std::optional<uint64_t> {
      if (!req.has_param(name)) return otherwise;
      const std::string v = req.get_param_value(name);
      if (v.empty() || v.size() > 12 || !std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; })) return std::nullopt;
      const uint64_t n = std::stoull(v);
      return n >= 1 && n <= most ? std::optional<uint64_t>(n) : std::nullopt;
    };
    const std::optional<uint64_t> limit = number("limit", kJobsPage, kMaxJobsPage);
    const std::optional<uint64_t> before = number("before", std::numeric_limits<uint64_t>::max(), std::numeric_limits<uint64_t>::max());
    if (!limit || !before)
      return refuse(res, 400, fmt::format("limit is 1 to {} and before a job's id", kMaxJobsPage));
    std::vector<cluster::Job> all = store_.list();  // in id order
    const std::size_t total = all.size();
    const auto end = std::partition_point(all.begin(), all.end(), [&](const cluster::Job& j) { return j.id < *before; });
    const auto begin = end - std::min<std::ptrdiff_t>(end - all.begin(), static_cast<std::ptrdiff_t>(*limit));
    json jobs = json::array();
    const std::vector<uint64_t> running = view_.running();
    for (auto it = begin; it != end; ++it) {
      const cluster::Job& j = *it;
      json o = job_object(j);
      if (std::optional<cluster::Status> st = view_.status(j.id)) {
        o["bundles_done"] = st->bundles_done;
        o["bundles"] = st->bundles;
        o["error_estimate"] = st->error_estimate;
        if (st->image_tiles > 0) {  // the final gather's tiles, rendered after the solve
          o["image_tiles"] = st->image_tiles;
          o["image_tiles_done"] = st->image_tiles_done;
        }
      }
      o["files"] = job_files(j, store_.folder(j.id));
      jobs.push_back(std::move(o));
    }
    reply(res, 200, {{"jobs", jobs}, {"running", running}, {"total", total}, {"older", begin - all.begin()}, {"viewer", viewer_available()}});
  });
  s.Get(R"(/api/jobs/(\d+))", [this, job_of](const httplib::Request& req, httplib::Response& res) {
    std::optional<cluster::Job> j = job_of(req, res);
    if (!j) return;
    json o = job_object(*j);
    o["files"] = job_files(*j, store_.folder(j->id));
    if (std::optional<cluster::Status> st = view_.status(j->id)) {
      o["status"] = json::parse(cluster::to_json(*st));
      json h = json::array();
      for (const FarmView::Point& p : view_.history(j->id)) h.push_back({p.elapsed_s, p.error_estimate, p.bundles_done});
      o["history"] = h;
    } else if (fs::is_regular_file(fs::path(store_.folder(j->id)) / "status.json")) {
      try {
        o["status"] = json::parse(read_file_whole((fs::path(store_.folder(j->id)) / "status.json").string(), "status", 1 << 24));
      } catch (const std::exception&) {  // being rewritten, or damaged: the job without it
      }
    }
    reply(res, 200, o);
  });
  s.Get(R"(/api/jobs/(\d+)/files/([A-Za-z0-9._-]+))", [this, job_of](const httplib::Request& req, httplib::Response& res) {
    std::optional<cluster::Job> j = job_of(req, res);
    if (!j) return;
    const std::string name = req.matches[2];
    const std::vector<std::string> files = job_files(*j, store_.folder(j->id));
    if (std::find(files.begin(), files.end(), name) == files.end()) return refuse(res, 404, "no such file of this job");
    const std::string ext = fs::path(name).extension().string();
    const char* type = ext == ".png" ? "image/png" : ext == ".json" ? "application/json" : ext == ".txt" ? "text/plain" : ext == ".csv" ? "text/csv" : ext == ".glb" ? "model/gltf-binary" : "application/octet-stream";
    send_file(res, fs::path(store_.folder(j->id)) / name, type);
  });
  // The 3D view of a job (/view?glb=/api/jobs/ID/glb&version=/api/jobs/ID/glb-version): the glb,
  // and its version (glb_version: "missing" while there is none) that the page
  // polls to load a running job's newer preview and then its result.
  serve_viewer(s, "/view");
  s.Get(R"(/api/jobs/(\d+)/glb)", [this, job_of](const httplib::Request& req, httplib::Response& res) {
    std::optional<cluster::Job> j = job_of(req, res);
    if (!j) return;
    const std::optional<fs::path> glb = job_glb(*j, store_.folder(j->id));
    if (!glb) return refuse(res, 404, "this job has no glb (yet)");
    res.set_header("Cache-Control", "no-store");
    send_file(res, *glb, "model/gltf-binary");
  });
  s.Get(R"(/api/jobs/(\d+)/glb-version)", [this, job_of](const httplib::Request& req, httplib::Response& res) {
    std::optional<cluster::Job> j = job_of(req, res);
    if (!j) return;
    const std::optional<fs::path> glb = job_glb(*j, store_.folder(j->id));
    res.set_header("Cache-Control", "no-store");
    res.set_content(glb ? glb_version(glb->string()) : std::string("missing"), "text/plain");
  });
  s.Post("/api/jobs", [this](const httplib::Request& req, httplib::Response& res) {
    try {
      if (!req.has_file("job")) fail("the request needs a 'job' part (JSON: name, scene, args, priority)");
      json spec;
      try {
        spec = parse_json_bounded(req.get_file_value("job").content, "job", cluster::kMaxJobFileBytes);
      } catch (const json::exception& e) {
        fail("job: not JSON: {}", e.what());
      }
      if (!spec.is_object()) fail("job: not a JSON object");
      // Each field of its kind or absent, checked before it is converted (a number converts to
      // an int by wrapping, a wrong kind to nlohmann's own message).
      auto text = [&](const char* key) {
        if (!spec.contains(key)) return std::string();
        if (!spec[key].is_string()) fail("job: '{}' is not a string", key);
        return spec[key].get<std::string>();
      };
      const std::string name = text("name"), scene = text("scene");
      int priority = 0;
      if (spec.contains("priority")) {
        const json& p = spec["priority"];
        const bool whole = p.is_number_integer() || (p.is_number_float() && std::isfinite(p.get<double>()) &&
                                                     p.get<double>() == std::trunc(p.get<double>()));
        const double v = whole ? p.get<double>() : 0.0;
        if (!whole || std::abs(v) > cluster::kMaxPriority)
          fail("job: 'priority' is a whole number within +-{}", cluster::kMaxPriority);
        priority = static_cast<int>(v);
      }
      std::vector<std::string> args;
      if (spec.contains("args")) {
        const json& a = spec["args"];
        if (!a.is_array() || !std::all_of(a.begin(), a.end(), [](const json& x) { return x.is_string(); }))
          fail("job: 'args' is not a list of strings");
        args = a.get<std::vector<std::string>>();
      }
      std::string bytes;
      if (req.has_file("scene_data")) {
        bytes = req.get_file_value("scene_data").content;
        decode_scene(bytes, "the uploaded scene");  // whole and sound, or refused now
        if (!scene.empty()) fail("job: 'scene' and an uploaded scene: give one");
      } else if (!is_builtin_scene(scene)) {
        fail("job: scene '{}' is not a built-in one (cornell, furnace, bright-room, three-lights); upload a file's scene",
             scene.substr(0, 80));
      }
      cluster::JobRun run = job_run(plan_job(args));  // the flags are checked now, not when the job comes to run
      cluster::Job job = store_.submit(name, scene, bytes, std::move(args), std::move(run), priority, unix_now());
      logging::write(logging::Level::info, "sirad-coordinator", fmt::format("job {} ({}) submitted", job.id, job.name),
                     {{"event", "job submitted"}, {"job", job.id}, {"address", req.get_header_value("X-Sirad-Peer")}});
      reply(res, 201, job_object(job));
    } catch (const json::exception& e) {
      refuse(res, 400, fmt::format("job: {}", e.what()));
    } catch (const Error& e) {
      refuse(res, 400, e.what());
    }
  });
  s.Post(R"(/api/jobs/(\d+)/cancel)", [this, job_of](const httplib::Request& req, httplib::Response& res) {
    std::optional<cluster::Job> j = job_of(req, res);
    if (!j) return;
    if (!store_.cancel(j->id, unix_now())) return refuse(res, 409, fmt::format("job {} has ended ({})", j->id, j->state));
    logging::write(logging::Level::info, "sirad-coordinator", fmt::format("job {} cancelled", j->id),
                   {{"event", "job cancel"}, {"job", j->id}, {"address", req.get_header_value("X-Sirad-Peer")}});
    reply(res, 200, job_object(*store_.get(j->id)));
  });
}

FarmHttp::~FarmHttp() { stop(); }

int FarmHttp::start(const std::string& host, int port) {
  const int inner = server_->bind_to_any_port("127.0.0.1");
  if (inner <= 0) fail("--http: cannot listen on a loopback port");
  thread_ = std::thread([this] { server_->listen_after_bind(); });
  guard_ = std::make_unique<HttpGuard>(inner);
  try {
    return guard_->start(host, port);
  } catch (const Error&) {
    stop();
    throw;
  }
}

void FarmHttp::stop() {
  if (guard_) guard_->stop();
  if (server_) server_->stop();
  if (thread_.joinable()) thread_.join();
}

}  // namespace sirad::cli
