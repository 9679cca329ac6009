// sirad: the 3D view's local page (see view_server.h).
#include "farm/view_server.h"

#include <httplib.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <fmt/format.h>

#include "cli/stop_signals.h"
#include "util/error.h"
#include "util/resources.h"

namespace sirad {

namespace {

namespace fs = std::filesystem;

// The page's modules, by the path the page's import map gives them, and their embedded names.
struct Module {
  const char* path;
  const char* resource;
};
constexpr Module kModules[] = {
    {"/three/three.module.min.js", "web/node_modules/three/build/three.module.min.js"},
    {"/three/addons/loaders/GLTFLoader.js", "web/node_modules/three/examples/jsm/loaders/GLTFLoader.js"},
    {"/three/addons/controls/OrbitControls.js", "web/node_modules/three/examples/jsm/controls/OrbitControls.js"},
    {"/three/addons/utils/BufferGeometryUtils.js", "web/node_modules/three/examples/jsm/utils/BufferGeometryUtils.js"},
};

// The glb's bytes, checked again at each request (it may be replaced while served).
bool read_glb(const std::string& path, std::string& bytes) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || !fs::is_regular_file(path, ec) || size > static_cast<std::uintmax_t>(kMaxViewBytes)) return false;
  std::ifstream in(path, std::ios::binary);
  bytes.assign(static_cast<std::size_t>(size), '\0');
  return static_cast<bool>(in.read(bytes.data(), static_cast<std::streamsize>(size)));
}

}  // namespace

bool viewer_available() {
#ifdef SIRAD_HAVE_THREE
  return true;
#else
  return false;
#endif
}

void serve_viewer(httplib::Server& s, const std::string& page) {
  s.Get(page, [](const httplib::Request&, httplib::Response& res) {
    // Its scripts (the import map, the page's own, three.js) and the glb from this server only;
    // the glb's embedded textures reach three.js as blob: URLs.
    res.set_header("Content-Security-Policy",
                   "default-src 'none'; script-src 'self' 'unsafe-inline'; style-src 'unsafe-inline'; "
                   "connect-src 'self' blob: data:; img-src 'self' blob: data:");
    res.set_content(std::string(resource("farm/viewer.html")), "text/html; charset=utf-8");
  });
  if (!viewer_available()) return;
  for (const Module& m : kModules) {
    const std::string_view text = resource(m.resource);
    s.Get(m.path, [text](const httplib::Request&, httplib::Response& res) {
      res.set_content(text.data(), text.size(), "text/javascript; charset=utf-8");
    });
  }
}

std::string glb_version(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec) return "missing";
  const auto time = fs::last_write_time(path, ec).time_since_epoch().count();
  return ec ? std::string("missing") : fmt::format("{}-{}-{}", fs::path(path).filename().string(), size, time);
}

struct ViewServer::Thread {
  std::thread t;
};

ViewServer::ViewServer(std::string glb) : glb_(std::move(glb)), server_(std::make_unique<httplib::Server>()) {
  std::error_code ec;
  if (!fs::is_regular_file(glb_, ec)) fail("{}: no such file", glb_);
  if (fs::file_size(glb_, ec) > static_cast<std::uintmax_t>(kMaxViewBytes)) fail("{}: larger than {} bytes", glb_, kMaxViewBytes);
  std::ifstream in(glb_, std::ios::binary);
  char magic[4] = {};
  if (!in.read(magic, 4) || std::string(magic, 4) != "glTF") fail("{}: not a binary glTF (.glb) file", glb_);
  if (!viewer_available())
    fail("sirad view: three.js was not installed when sirad was built: run deploy/install-deps.sh (npm ci in web/), then build again");
  httplib::Server& s = *server_;
  s.set_read_timeout(5, 0);
  s.set_write_timeout(30, 0);
  s.set_payload_max_length(4096);
  serve_viewer(s, "/");
  s.Get("/scene.glb", [this](const httplib::Request&, httplib::Response& res) {
    std::string bytes;
    if (!read_glb(glb_, bytes)) {
      res.status = 404;
      res.set_content(fmt::format("{} cannot be read\n", glb_), "text/plain");
      return;
    }
    res.set_header("Cache-Control", "no-store");
    res.set_content(std::move(bytes), "model/gltf-binary");
  });
  s.Get("/version", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(glb_version(glb_), "text/plain");
  });
}

ViewServer::~ViewServer() { stop(); }

int ViewServer::start(const std::string& host, int port) {
  const int bound = port == 0 ? server_->bind_to_any_port(host) : (server_->bind_to_port(host, port) ? port : -1);
  if (bound <= 0) fail("sirad view: cannot listen on {}:{}", host, port);
  thread_ = std::make_unique<Thread>();
  thread_->t = std::thread([this] { server_->listen_after_bind(); });
  return bound;
}

void ViewServer::stop() {
  if (server_) server_->stop();
  if (thread_ && thread_->t.joinable()) thread_->t.join();
}

int view_command(const std::string& glb, const std::string& host, int port) {
  const std::atomic<bool>& stop = cli::stop_on_signals();
  ViewServer server(glb);
  const int bound = server.start(host, port);
  std::printf("view %s at http://%s:%d/ (Ctrl-C to stop)\n", glb.c_str(), host.c_str(), bound);
  std::fflush(stdout);
  while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(200));  // a signal's flag: nothing else to wait on
  server.stop();
  return 0;
}

}  // namespace sirad
