// sirad: the bytes libzmq holds per TCP peer, watched and bounded (peer_bytes.h).
#include "proto/peer_bytes.h"

#include <linux/sockios.h>
#include <linux/tcp.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/ioctl.h>
#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include <fmt/format.h>

namespace sirad::proto {

namespace {

// What the kernel has received on a TCP connection and what of it still waits to be read; false
// for a descriptor that is not (or no longer) a TCP connection.
bool tcp_bytes(int fd, uint64_t& received, uint64_t& waiting) {
  tcp_info info{};
  socklen_t length = sizeof info;
  if (::getsockopt(fd, IPPROTO_TCP, TCP_INFO, &info, &length) != 0 ||
      length < offsetof(tcp_info, tcpi_bytes_received) + sizeof info.tcpi_bytes_received)
    return false;
  int queued = 0;
  if (::ioctl(fd, SIOCINQ, &queued) != 0) return false;
  received = info.tcpi_bytes_received;
  waiting = static_cast<uint64_t>(std::max(queued, 0));
  return true;
}

// The peer's address of a connection, as "ADDRESS:PORT" ("?" if it cannot be told).
std::string peer_address(int fd) {
  sockaddr_storage a{};
  socklen_t length = sizeof a;
  char text[INET6_ADDRSTRLEN] = "?";
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&a), &length) != 0) return "?";
  if (a.ss_family == AF_INET) {
    const auto* v4 = reinterpret_cast<const sockaddr_in*>(&a);
    ::inet_ntop(AF_INET, &v4->sin_addr, text, sizeof text);
    return fmt::format("{}:{}", text, ntohs(v4->sin_port));
  }
  if (a.ss_family == AF_INET6) {
    const auto* v6 = reinterpret_cast<const sockaddr_in6*>(&a);
    ::inet_ntop(AF_INET6, &v6->sin6_addr, text, sizeof text);
    return fmt::format("[{}]:{}", text, ntohs(v6->sin6_port));
  }
  return "?";
}

std::atomic<uint64_t> next_monitor{0};

}  // namespace

PeerBytes::PeerBytes(zmq::context_t& context, zmq::socket_t& socket, uint64_t bound,
                     std::function<void(const std::string& address, uint64_t held)> on_shut)
    : bound_(bound), on_shut_(std::move(on_shut)), events_(context, zmq::socket_type::pair) {
  const std::string endpoint = fmt::format("inproc://sirad-peer-bytes-{}", next_monitor++);
  if (zmq_socket_monitor(socket.handle(), endpoint.c_str(), ZMQ_EVENT_ACCEPTED | ZMQ_EVENT_DISCONNECTED | ZMQ_EVENT_CLOSED) != 0)
    throw zmq::error_t();
  events_.set(zmq::sockopt::linger, 0);
  events_.connect(endpoint);
  thread_ = std::thread([this] { watch(); });
}

PeerBytes::~PeerBytes() {
  stopping_ = true;
  if (thread_.joinable()) thread_.join();
}

void PeerBytes::delivered(int fd, std::size_t frames, std::size_t bytes) {
  if (fd < 0) return;
  std::lock_guard lock(mutex_);
  auto it = conns_.find(fd);
  if (it == conns_.end()) return;
  it->second.frames += frames;
  it->second.bytes += bytes;
}

void PeerBytes::watch() {
  double period = kMinCheckS;
  while (!stopping_) {
    // The monitor's events until the next check: a connection accepted starts from nothing (a
    // descriptor libzmq closed may come back as another connection), one that ended goes.
    // A signal (the process's SIGTERM handler may run on this thread) only ends the wait early.
    try {
      zmq::pollitem_t item{events_.handle(), 0, ZMQ_POLLIN, 0};
      zmq::poll(&item, 1, std::chrono::milliseconds(static_cast<int64_t>(period * 1e3)));
      zmq::message_t event, address;
      while (events_.recv(event, zmq::recv_flags::dontwait)) {
        if (!event.more() || !events_.recv(address) || event.size() < 6) continue;
        uint16_t what = 0;
        int32_t fd = -1;
        std::memcpy(&what, event.data(), 2);
        std::memcpy(&fd, static_cast<const char*>(event.data()) + 2, 4);
        std::lock_guard lock(mutex_);
        if (what == ZMQ_EVENT_ACCEPTED) conns_[fd] = Conn{peer_address(fd)};
        else conns_.erase(fd);
      }
    } catch (const zmq::error_t& e) {
      if (e.num() != EINTR) return;  // the context is ending: nothing more to watch
    }
    std::vector<std::pair<std::string, uint64_t>> shut;
    {
      std::lock_guard lock(mutex_);
      period = std::clamp(kCheckSPerConnection * static_cast<double>(conns_.size()), kMinCheckS, kMaxCheckS);
      for (auto& [fd, c] : conns_) {
        uint64_t received = 0, waiting = 0;
        if (c.shut || !tcp_bytes(fd, received, waiting)) continue;
        const uint64_t accounted = waiting + c.bytes + kHandshakeBytes + kFrameBytes * c.frames;
        const uint64_t held = received > accounted ? received - accounted : 0;
        if (held <= bound_) continue;
        ::shutdown(fd, SHUT_RDWR);
        c.shut = true;
        shut.emplace_back(c.address, held);
      }
    }
    for (const auto& [address, held] : shut) {
      ++shut_;
      if (on_shut_) on_shut_(address, held);
    }
  }
}

}  // namespace sirad::proto
