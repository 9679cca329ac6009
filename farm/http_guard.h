// sirad: the front of the farm's HTTP server (`sirad-coordinator --serve --http`). cpp-httplib
// serves each connection on a thread of a small pool from its first byte, so a few clients
// that send their request slowly (or never) hold every thread and freeze the page and the API
// for everyone. The guard takes the public address instead: one thread and epoll hold any
// number of connections for the price of their buffers, and a request reaches the HTTP server
// (on a loopback port of its own) only once its head is complete. So no thread waits on a
// client's head, and every byte after it must move at kMinRate.
//
// Its bounds, per connection: the request's head within kHeadSeconds of the connection and at
// most kMaxHead bytes (else 408 or 431, then a lingering close: the guard stops writing and
// reads and drops what the client still sends, up to kLingerBytes or kLingerSeconds, so that
// the answer is not lost to a reset while the client is still sending; RFC 9112 section 9.6);
// after the head, the body and the response
// each at kMinRate bytes a second on average, counted from kHeadSeconds after the head (else
// closed); one request per connection (the server closes after each answer). Per client
// address at most kPerClient connections at once, kMaxConnections in all (else 503, closed).
// The server learns the client's address from the header X-Sirad-Peer, which the guard sets
// (and removes when a client sends it).
#pragma once
#include <atomic>
#include <cstddef>
#include <string>
#include <thread>

namespace sirad::cli {

class HttpGuard {
 public:
  static constexpr double kHeadSeconds = 10.0;
  static constexpr double kMinRate = 16384.0;  // bytes a second
  static constexpr std::size_t kMaxHead = 16384;
  static constexpr std::size_t kPerClient = 64, kMaxConnections = 1024;
  static constexpr std::size_t kBuffer = std::size_t{64} << 10;  // per direction and connection
  static constexpr double kLingerSeconds = 2.0;
  static constexpr std::size_t kLingerBytes = std::size_t{256} << 10;

  // Forwards to the HTTP server at 127.0.0.1:`backend_port`.
  explicit HttpGuard(int backend_port);
  ~HttpGuard();
  HttpGuard(const HttpGuard&) = delete;
  HttpGuard& operator=(const HttpGuard&) = delete;

  // Binds HOST:PORT (port 0: any free one) and serves on a thread of its own; returns the port.
  // Throws sirad::Error when it cannot bind.
  int start(const std::string& host, int port);
  void stop();

 private:
  void loop();

  int backend_port_;
  int listen_fd_ = -1, wake_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

}  // namespace sirad::cli
