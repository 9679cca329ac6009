// sirad: the front of the farm's HTTP server (see http_guard.h).
#include "farm/http_guard.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <map>
#include <memory>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "util/error.h"

namespace sirad::cli {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point from, Clock::time_point now) { return std::chrono::duration<double>(now - from).count(); }

bool iequal(std::string_view a, std::string_view b) {
  return a.size() == b.size() &&
         std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) { return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y)); });
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// A short answer the guard gives itself, sent as far as the socket takes it, then closed.
void answer(int fd, const char* status) {
  const std::string text = std::string("HTTP/1.1 ") + status + "\r\nConnection: close\r\nContent-Length: 0\r\n\r\n";
  [[maybe_unused]] ssize_t n = ::send(fd, text.data(), text.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

// One client's connection and, once its head is in, the server's.
struct Conn {
  int client = -1, backend = -1;
  std::string ip;
  Clock::time_point opened, head_done, first_answer;
  std::string head;      // the request's head until it is complete
  std::string up, down;  // bytes on their way to the server, to the client
  bool relaying = false, answering = false, client_eof = false, backend_eof = false, chunked = false;
  uint64_t body_length = 0, body_read = 0, answered = 0;
  bool draining = false;  // refused: its answer sent, what the client still sends is dropped
  Clock::time_point drain_from;
  uint64_t drained = 0;
  uint32_t client_mask = 0, backend_mask = 0;  // the epoll interests armed
};

}  // namespace

HttpGuard::HttpGuard(int backend_port) : backend_port_(backend_port) {}

HttpGuard::~HttpGuard() { stop(); }

int HttpGuard::start(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found) != 0 || !found)
    fail("--http {}:{}: cannot listen there (no such address)", host, port);
  std::unique_ptr<addrinfo, decltype(&::freeaddrinfo)> list(found, &::freeaddrinfo);
  for (addrinfo* a = found; a && listen_fd_ < 0; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, 512) == 0) listen_fd_ = fd;
    else ::close(fd);
  }
  if (listen_fd_ < 0) fail("--http {}:{}: cannot listen there", host, port);
  sockaddr_storage bound{};
  socklen_t len = sizeof bound;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &len);
  const int actual = ntohs(bound.ss_family == AF_INET6 ? reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port
                                                       : reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_fd_ < 0) fail("--http: cannot make an eventfd: {}", std::strerror(errno));
  thread_ = std::thread([this] { loop(); });
  return actual;
}

void HttpGuard::stop() {
  if (thread_.joinable()) {
    stopping_ = true;
    const uint64_t one = 1;
    [[maybe_unused]] ssize_t n = ::write(wake_fd_, &one, sizeof one);
    thread_.join();
  }
  if (listen_fd_ >= 0) ::close(listen_fd_);
  if (wake_fd_ >= 0) ::close(wake_fd_);
  listen_fd_ = wake_fd_ = -1;
}

namespace {

// The guard's one thread: an epoll set over the public socket, the wake-up eventfd and every
// connection's two sockets, and the bounds of each connection (see http_guard.h).
class Front {
 public:
  Front(int backend_port, int listen_fd, int wake_fd)
      : backend_port_(backend_port), listen_fd_(listen_fd), wake_fd_(wake_fd), ep_(::epoll_create1(EPOLL_CLOEXEC)) {
    if (ep_ < 0) return;
    watch(listen_fd_, EPOLLIN);
    watch(wake_fd_, EPOLLIN);
  }
  ~Front() {
    std::vector<std::shared_ptr<Conn>> all;
    for (const auto& [fd, c] : by_fd_) all.push_back(c);
    for (const auto& c : all)
      if (c->client >= 0 || c->backend >= 0) close_conn(c);
    if (ep_ >= 0) ::close(ep_);
  }
  Front(const Front&) = delete;
  Front& operator=(const Front&) = delete;
  bool ok() const { return ep_ >= 0; }

  // Waits up to `wait_ms` for events, handles them, then closes the connections past a bound of time.
  void turn(int wait_ms) {
    const int n = ::epoll_wait(ep_, events_.data(), static_cast<int>(events_.size()), wait_ms);
    const auto now = Clock::now();
    for (int k = 0; k < std::max(n, 0); ++k) {
      const int fd = events_[k].data.fd;
      if (fd == wake_fd_) continue;
      if (fd == listen_fd_) {
        accept_all(now);
        continue;
      }
      auto it = by_fd_.find(fd);
      if (it == by_fd_.end()) continue;
      const std::shared_ptr<Conn> c = it->second;
      const uint32_t ev = events_[k].events;
      const bool dead = fd == c->client ? from_client(c, ev, now) : from_backend(*c, ev, now);
      settle(c, dead);
    }
    close_late(now);
  }

 private:
  void watch(int fd, uint32_t mask) {
    epoll_event e{};
    e.events = mask;
    e.data.fd = fd;
    ::epoll_ctl(ep_, EPOLL_CTL_ADD, fd, &e);
  }

  // Every connection waiting on the public socket: refused with 503 beyond kMaxConnections in
  // all or kPerClient from its address.
  void accept_all(Clock::time_point now) {
    for (;;) {
      sockaddr_storage from{};
      socklen_t len = sizeof from;
      const int s = ::accept4(listen_fd_, reinterpret_cast<sockaddr*>(&from), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (s < 0) break;
      char ip[INET6_ADDRSTRLEN] = "?";
      if (from.ss_family == AF_INET) ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(&from)->sin_addr, ip, sizeof ip);
      else if (from.ss_family == AF_INET6) ::inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(&from)->sin6_addr, ip, sizeof ip);
      if (open_ >= HttpGuard::kMaxConnections || per_client_[ip] >= HttpGuard::kPerClient) {
        if (per_client_[ip] == 0) per_client_.erase(ip);
        answer(s, "503 Service Unavailable");
        ::close(s);
        continue;
      }
      auto c = std::make_shared<Conn>();
      c->client = s;
      c->ip = ip;
      c->opened = now;
      ++per_client_[c->ip];
      ++open_;
      by_fd_[s] = c;
      watch(s, EPOLLIN);
      c->client_mask = EPOLLIN;
    }
  }

  // Events on a client's socket: its head, then its body on its way to the server; the answer
  // on its way to it; what a refused client still sends, dropped. Returns whether it is done for.
  bool from_client(const std::shared_ptr<Conn>& c, uint32_t ev, Clock::time_point now) {
    const int fd = c->client;
    if (ev & (EPOLLHUP | EPOLLERR)) return true;  // gone: nothing can reach it any more
    if ((ev & EPOLLIN) && c->draining) {
      const ssize_t r = ::recv(fd, buffer_.data(), buffer_.size(), 0);
      if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return true;
      if (r > 0 && (c->drained += static_cast<uint64_t>(r)) > HttpGuard::kLingerBytes) return true;
    } else if ((ev & EPOLLIN) && !c->relaying) {
      const std::size_t room = HttpGuard::kMaxHead + 1 - c->head.size();
      const ssize_t r = ::recv(fd, buffer_.data(), std::min(room, buffer_.size()), 0);
      if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return true;
      if (r > 0) {
        c->head.append(buffer_.data(), static_cast<std::size_t>(r));
        const std::size_t end = c->head.find("\r\n\r\n");
        if (end != std::string::npos && end + 4 <= HttpGuard::kMaxHead) {
          if (!relay(c, end + 4)) return true;
        } else if (c->head.size() > HttpGuard::kMaxHead) {
          refuse(*c, "431 Request Header Fields Too Large", now);
        }
      }
    } else if ((ev & EPOLLIN) && c->up.size() < HttpGuard::kBuffer) {
      const ssize_t r = ::recv(fd, buffer_.data(), std::min(HttpGuard::kBuffer - c->up.size(), buffer_.size()), 0);
      if (r > 0) {
        c->up.append(buffer_.data(), static_cast<std::size_t>(r));
        c->body_read += static_cast<uint64_t>(r);
      } else if (r == 0) {
        c->client_eof = true;
      } else if (errno != EAGAIN && errno != EWOULDBLOCK) {
        return true;
      }
    }
    if ((ev & EPOLLOUT) && !c->down.empty()) {
      const ssize_t w = ::send(fd, c->down.data(), c->down.size(), MSG_NOSIGNAL);
      if (w > 0) {
        c->down.erase(0, static_cast<std::size_t>(w));
        c->answered += static_cast<uint64_t>(w);
      } else if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
        return true;
      }
    }
    return false;
  }

  // Events on the server's socket: its answer on its way to the client, the request to it.
  // Hung up, the server has sent all it will: what its socket holds (a kernel buffer) is taken
  // at once whatever the room, so no event repeats while the client is slow.
  bool from_backend(Conn& c, uint32_t ev, Clock::time_point now) {
    const bool hung_up = ev & (EPOLLHUP | EPOLLERR);
    if (((ev & EPOLLIN) && c.down.size() < HttpGuard::kBuffer) || hung_up) {
      const ssize_t r = ::recv(c.backend, buffer_.data(),
                               hung_up ? buffer_.size() : std::min(HttpGuard::kBuffer - c.down.size(), buffer_.size()), 0);
      if (r > 0) {
        if (!c.answering) c.first_answer = now;
        c.answering = true;
        c.down.append(buffer_.data(), static_cast<std::size_t>(r));
      } else if (r == 0 || (errno != EAGAIN && errno != EWOULDBLOCK)) {
        c.backend_eof = true;
      }
    }
    if ((ev & EPOLLOUT) && !c.up.empty()) {
      const ssize_t w = ::send(c.backend, c.up.data(), c.up.size(), MSG_NOSIGNAL);
      if (w > 0) c.up.erase(0, static_cast<std::size_t>(w));
      else if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK) return true;
    }
    return false;
  }

  // After a connection's events: the server's socket closed once its answer is all in `down`,
  // the server told the request is over once the client's is, the connection closed when it is
  // done for or answered in full, else its interests armed again.
  void settle(const std::shared_ptr<Conn>& c, bool dead) {
    if (!dead && c->backend_eof && c->backend >= 0) {
      ::epoll_ctl(ep_, EPOLL_CTL_DEL, c->backend, nullptr);
      ::close(c->backend);
      by_fd_.erase(c->backend);
      c->backend = -1;
      c->up.clear();
    }
    if (!dead && c->client_eof && c->up.empty() && c->backend >= 0) ::shutdown(c->backend, SHUT_WR);
    if (!dead && c->relaying && c->backend_eof && c->down.empty()) dead = true;  // answered in full
    if (!dead && !c->relaying && c->client_eof) dead = true;
    if (dead) close_conn(c);
    else arm(*c);
  }

  // The bounds of time: the head, then the body and the answer at kMinRate after a grace of
  // kHeadSeconds each; a refused connection's lingering close.
  void close_late(Clock::time_point now) {
    std::vector<std::shared_ptr<Conn>> late;
    for (const auto& [fd, c] : by_fd_) {
      if (fd != c->client) continue;
      if (c->draining) {
        if (since(c->drain_from, now) > HttpGuard::kLingerSeconds) late.push_back(c);
        continue;
      }
      if (!c->relaying) {
        if (since(c->opened, now) > HttpGuard::kHeadSeconds) refuse(*c, "408 Request Timeout", now);
        continue;
      }
      const double owed = (since(c->head_done, now) - HttpGuard::kHeadSeconds) * HttpGuard::kMinRate;
      const bool body_due = c->chunked ? !c->answering && !c->client_eof : c->body_read < c->body_length;
      if (body_due && static_cast<double>(c->body_read) < owed) late.push_back(c);
      else if (c->answering && !c->down.empty() &&
               static_cast<double>(c->answered) < (since(c->first_answer, now) - HttpGuard::kHeadSeconds) * HttpGuard::kMinRate)
        late.push_back(c);
    }
    for (const auto& c : late)
      if (c->client >= 0) close_conn(c);
  }

  void close_conn(const std::shared_ptr<Conn>& c) {
    if (c->client < 0 && c->backend < 0) return;
    for (int fd : {c->client, c->backend})
      if (fd >= 0) {
        ::epoll_ctl(ep_, EPOLL_CTL_DEL, fd, nullptr);
        ::close(fd);
        by_fd_.erase(fd);
      }
    c->client = c->backend = -1;
    if (--per_client_[c->ip] == 0) per_client_.erase(c->ip);
    --open_;
  }

  // The interests that move a connection on: read what there is room for, write what waits.
  void arm(Conn& c) {
    auto set = [&](int fd, uint32_t& armed, uint32_t want) {
      if (fd < 0 || armed == want) return;
      epoll_event e{};
      e.events = want;
      e.data.fd = fd;
      ::epoll_ctl(ep_, EPOLL_CTL_MOD, fd, &e);
      armed = want;
    };
    uint32_t client = 0, backend = 0;
    if (!c.client_eof && (!c.relaying || c.up.size() < HttpGuard::kBuffer)) client |= EPOLLIN;
    if (!c.down.empty()) client |= EPOLLOUT;
    if (c.relaying) {
      if (!c.backend_eof && c.down.size() < HttpGuard::kBuffer) backend |= EPOLLIN;
      if (!c.up.empty()) backend |= EPOLLOUT;
    }
    set(c.client, c.client_mask, client);
    set(c.backend, c.backend_mask, backend);
  }

  // The guard's own answer to a request it refuses before its head is in, then the lingering
  // close: no more writing, the client's bytes read and dropped (kLingerBytes, kLingerSeconds).
  static void refuse(Conn& c, const char* status, Clock::time_point now) {
    answer(c.client, status);
    ::shutdown(c.client, SHUT_WR);
    c.draining = true;
    c.drain_from = now;
    c.head.clear();
    c.head.shrink_to_fit();
  }

  // The head is in (its first `end` bytes): passed on to the server with the client's address
  // and one request per connection. False (503 sent) when the server cannot be reached.
  bool relay(const std::shared_ptr<Conn>& c, std::size_t end) {
    std::string out = forwarded_head(*c, std::string_view(c->head.data(), end));
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(backend_port_));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd < 0 || ::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) != 0) {  // loopback: at once
      if (fd >= 0) ::close(fd);
      answer(c->client, "503 Service Unavailable");
      return false;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
    c->backend = fd;
    by_fd_[fd] = c;
    watch(fd, 0);
    c->backend_mask = 0;
    c->body_read = c->head.size() - end;  // what came with the head
    c->up = std::move(out) + c->head.substr(end);
    c->head.clear();
    c->head.shrink_to_fit();
    c->relaying = true;
    c->head_done = Clock::now();
    return true;
  }

  // The head as the server gets it: X-Sirad-Peer (the client's address) and Connection: close
  // in place of any the client sent; its body's length or chunking noted in `c`.
  static std::string forwarded_head(Conn& c, std::string_view head) {
    std::string out;
    std::size_t at = head.find("\r\n");
    out.append(head.substr(0, at + 2));
    out += "X-Sirad-Peer: " + c.ip + "\r\nConnection: close\r\n";
    for (at += 2; at < head.size();) {
      const std::size_t next = head.find("\r\n", at);
      const std::string_view line = head.substr(at, next - at);
      at = next + 2;
      if (line.empty()) break;
      const std::size_t colon = line.find(':');
      const std::string_view name = trim(line.substr(0, colon)), value = colon == std::string_view::npos ? "" : trim(line.substr(colon + 1));
      if (iequal(name, "X-Sirad-Peer") || iequal(name, "Connection")) continue;
      if (iequal(name, "Content-Length")) {
        uint64_t n = 0;
        for (char ch : value) n = ch >= '0' && ch <= '9' && n < (uint64_t{1} << 40) ? 10 * n + static_cast<uint64_t>(ch - '0') : n;
        c.body_length = n;
      }
      if (iequal(name, "Transfer-Encoding")) c.chunked = true;
      out.append(line);
      out += "\r\n";
    }
    out += "\r\n";
    return out;
  }

  int backend_port_, listen_fd_, wake_fd_, ep_;
  std::unordered_map<int, std::shared_ptr<Conn>> by_fd_;  // both of a connection's sockets
  std::map<std::string, std::size_t> per_client_;
  std::size_t open_ = 0;
  std::vector<epoll_event> events_ = std::vector<epoll_event>(128);
  std::vector<char> buffer_ = std::vector<char>(64 * 1024);
};

}  // namespace

void HttpGuard::loop() {
  Front front(backend_port_, listen_fd_, wake_fd_);
  if (!front.ok()) return;
  while (!stopping_) front.turn(200);
}

}  // namespace sirad::cli
