// sirad: `sirad view RESULT.glb`, the 3D view of a result on a local page: farm/viewer.html and
// three.js (web/package.json's, embedded at build time) served with the glb by cpp-httplib on a
// loopback port. The page loads /scene.glb and polls /version (glb_version): a rebake, or a running job's newer glb, shows as it lands. The farm's page serves the
// same page for its jobs (serve_viewer).
#pragma once
#include <memory>
#include <string>

namespace httplib {
class Server;
}

namespace sirad {

// Whether three.js was embedded when sirad was built (web/node_modules present: deploy/install-deps.sh
// runs npm ci there).
bool viewer_available();

// Serves the 3D view's page (farm/viewer.html) at `page` and three.js's modules where its import
// map finds them (/three/...). The page loads /scene.glb and polls /version unless its query
// names other paths of the same server (?glb=PATH&version=PATH: the farm's page shows a job's).
void serve_viewer(httplib::Server& server, const std::string& page);

// What the page polls to reload a glb: the file's name, size and modification time, or
// "missing" where it cannot be read.
std::string glb_version(const std::string& path);

class ViewServer {
 public:
  // Serves `glb` (refused, naming it, if it is not a readable glb of at most kMaxViewBytes).
  explicit ViewServer(std::string glb);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;
  // Listens on `host`:`port` (0: any free port) on a thread of its own; returns the port.
  int start(const std::string& host, int port);
  void stop();

 private:
  std::string glb_;
  std::unique_ptr<httplib::Server> server_;
  struct Thread;
  std::unique_ptr<Thread> thread_;
};

inline constexpr long long kMaxViewBytes = 1LL << 31;

// `sirad view`: serves until SIGINT or SIGTERM, the page's address on stdout first.
int view_command(const std::string& glb, const std::string& host, int port);

}  // namespace sirad
