// sirad: the farm's HTTP API and web page (cpp-httplib), served by `sirad-coordinator --serve`
// beside its ZeroMQ endpoint (proto/PROTOCOL.md section 10), behind farm/http_guard.h (slow and
// many clients). Reading (jobs, their progress and nodes, outputs) is open to whoever reaches
// the address (localhost unless asked); submitting and cancelling need the farm's token
// ("Authorization: Bearer TOKEN").
#pragma once
#include <memory>
#include <string>
#include <thread>

#include "cluster/jobs.h"
#include "farm/farm.h"
#include "farm/http_guard.h"

namespace httplib {
class Server;
}

namespace sirad::cli {

// The farm's token: read from `path` (it must be a file only its owner may read, 16 to 256
// printable bytes), or, when `path` does not exist, made there (32 random bytes in hex, mode
// 0600). Throws sirad::Error naming the file.
std::string farm_token(const std::string& path);

class FarmHttp {
 public:
  // A cancel marks the job in `store`; the farm stops it.
  FarmHttp(cluster::JobStore& store, FarmView& view, std::string token);
  ~FarmHttp();
  // Binds HOST:PORT (port 0: any free one) and serves on a thread of its own; returns the port.
  // Throws sirad::Error when it cannot bind.
  int start(const std::string& host, int port);
  void stop();

 private:
  cluster::JobStore& store_;
  FarmView& view_;
  std::string token_;
  std::unique_ptr<httplib::Server> server_;  // on a loopback port of its own, behind guard_
  std::unique_ptr<HttpGuard> guard_;          // the public address
  std::thread thread_;
};

}  // namespace sirad::cli
