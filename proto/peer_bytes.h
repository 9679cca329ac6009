// sirad: a bound on the bytes libzmq holds for each TCP peer of a bound socket.
//
// libzmq holds a multipart message whole before the receiver can read any of it, and it has no
// bound on a message's frames (ZMQ_MAXMSGSIZE bounds each frame): a peer that can connect could
// make the receiver hold gigabytes in one message. PeerBytes watches each connection the socket
// accepts (a socket monitor's ACCEPTED event carries its descriptor) from a thread of its own:
// what the kernel has received on it (TCP_INFO's tcpi_bytes_received), less what still waits in
// the kernel (SIOCINQ), less what the receiver has been handed from it (delivered(): a message's
// ZMQ_SRCFD names its connection), less the framing of what was handed (kFrameBytes a frame and
// kHandshakeBytes, more than ZMTP and CURVE take), is a lower bound on what libzmq holds for it.
// Past `bound`, the connection is shut down (shutdown(2) on libzmq's descriptor: libzmq sees
// the connection end, drops it and the partial message, and frees them; the peer may connect
// again). The check runs every kMinCheckS, or every kCheckSPerConnection per connection
// watched where that is longer (at most kMaxCheckS; a check costs about 2 us per connection),
// so a peer holds at most `bound` plus what its link carries in one period.
//
// Linux only (TCP_INFO's byte counts, SIOCINQ). Connections other than TCP (ipc://, inproc://)
// are not watched.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>

#include <zmq.hpp>

namespace sirad::proto {

class PeerBytes {
 public:
  static constexpr uint64_t kFrameBytes = 64, kHandshakeBytes = 8192;
  static constexpr double kMinCheckS = 0.01, kMaxCheckS = 0.25, kCheckSPerConnection = 1e-4;

  // Watches the connections `socket` accepts from now on (construct it before the socket binds,
  // on the socket's thread); each may hold at most `bound` bytes. `on_shut`, called on the
  // watcher's thread, hears of each connection shut down (its peer's address and what it held).
  PeerBytes(zmq::context_t& context, zmq::socket_t& socket, uint64_t bound,
            std::function<void(const std::string& address, uint64_t held)> on_shut);
  // Stops the watcher; before the socket closes.
  ~PeerBytes();
  PeerBytes(const PeerBytes&) = delete;
  PeerBytes& operator=(const PeerBytes&) = delete;

  // The receiver was handed a message of `frames` frames and `bytes` bytes from connection
  // `fd` (zmq_msg_get ZMQ_SRCFD of its frames; < 0: none, nothing counted).
  void delivered(int fd, std::size_t frames, std::size_t bytes);
  // Connections shut down so far.
  uint64_t shut() const { return shut_.load(); }

 private:
  struct Conn {
    std::string address;
    uint64_t bytes = 0, frames = 0;  // handed to the receiver
    bool shut = false;
  };
  void watch();

  uint64_t bound_;
  std::function<void(const std::string&, uint64_t)> on_shut_;
  zmq::socket_t events_;  // the monitor's PAIR, read by the watcher only
  std::mutex mutex_;
  std::unordered_map<int, Conn> conns_;  // by descriptor
  std::atomic<bool> stopping_{false};
  std::atomic<uint64_t> shut_{0};
  std::thread thread_;
};

}  // namespace sirad::proto
