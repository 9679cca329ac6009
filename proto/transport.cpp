// sirad: SIRAD/1 over ZeroMQ: multipart send and receive with a timeout.
#include "proto/transport.h"

#include "util/error.h"

#include <cerrno>
#include <algorithm>
#include <cstring>
#include <limits>

namespace sirad::proto {

void check_endpoint(const std::string& flag, const std::string& endpoint, bool bind) {
  auto scheme_end = endpoint.find("://");
  if (scheme_end == std::string::npos) fail("{} {}: expected tcp://HOST:PORT, ipc://PATH or inproc://NAME", flag, endpoint);
  std::string scheme = endpoint.substr(0, scheme_end), rest = endpoint.substr(scheme_end + 3);
  if (scheme == "ipc" || scheme == "inproc") {
    if (rest.empty()) fail("{} {}: empty {} name", flag, endpoint, scheme);
    return;
  }
  if (scheme != "tcp") fail("{} {}: unknown transport '{}' (tcp, ipc or inproc)", flag, endpoint, scheme);
  auto colon = rest.rfind(':');
  if (colon == std::string::npos || colon == 0) fail("{} {}: expected tcp://HOST:PORT", flag, endpoint);
  std::string host = rest.substr(0, colon), port = rest.substr(colon + 1);
  if (host == "*" && !bind) fail("{} {}: '*' is only for binding; name the coordinator's host", flag, endpoint);
  if (bind && (port == "*" || port == "0")) return;
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) < 1 || std::stoi(port) > 65535)
    fail("{} {}: port '{}' is not in 1..65535", flag, endpoint, port);
}

void harden(zmq::socket_t& socket, int64_t max_frame_bytes) {
  const bool router = socket.get(zmq::sockopt::type) == static_cast<int>(zmq::socket_type::router);
  socket.set(zmq::sockopt::maxmsgsize, max_frame_bytes);
  socket.set(zmq::sockopt::sndtimeo, router ? 0 : kSendTimeoutMs);
  socket.set(zmq::sockopt::handshake_ivl, kHandshakeMs);
  if (router) socket.set(zmq::sockopt::router_mandatory, 1);
}

int64_t max_frame_bytes(std::size_t patches, bool with_scene) {
  const uint64_t chunk = 24 * static_cast<uint64_t>(patches);
  const uint64_t largest = std::max<uint64_t>({chunk, with_scene ? kMaxSceneFrameBytes : 0, kMaxHeaderBytes});
  return static_cast<int64_t>(std::min<uint64_t>(largest + 64 * 1024, std::numeric_limits<int64_t>::max()));
}

uint64_t max_peer_bytes(std::size_t patches) {
  return 4 * static_cast<uint64_t>(max_frame_bytes(patches)) + (uint64_t{4} << 20);
}

bool send(zmq::socket_t& socket, const Message& message, const std::string* routing_id) {
  std::vector<std::string> frames = encode(message);
  if (routing_id) frames.insert(frames.begin(), *routing_id);
  return send_frames(socket, frames);
}

bool send_frames(zmq::socket_t& socket, const std::vector<std::string>& frames) {
  for (std::size_t i = 0; i < frames.size(); ++i) {
    try {
      // Only the first frame can fail (the peer's queue is chosen there); the rest follow it.
      if (!socket.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none))
        return false;  // EAGAIN: its queue was full (for the send timeout, if any)
    } catch (const zmq::error_t& e) {
      if (e.num() == EHOSTUNREACH) return false;  // ROUTER_MANDATORY: no such peer (any more)
      throw;
    }
  }
  return true;
}

bool ShapedLink::send(zmq::socket_t& socket, std::vector<std::string> frames, double now) {
  if (!model_.shaped()) return send_frames(socket, frames);
  std::size_t bytes = 0;
  for (const auto& f : frames) bytes += f.size();
  double due = model_.deliver(now, bytes);
  if (!queue_.empty()) due = std::max(due, queue_.back().first);
  queue_.emplace_back(due, std::move(frames));
  flush(socket, now);
  return true;
}

double ShapedLink::flush(zmq::socket_t& socket, double now) {
  while (!queue_.empty() && queue_.front().first <= now) {
    failed_ += !send_frames(socket, queue_.front().second);
    queue_.pop_front();
  }
  return queue_.empty() ? std::numeric_limits<double>::infinity() : queue_.front().first;
}

namespace {

// Waits up to `timeout_ms` for a message; false on a timeout or a signal.
bool readable(zmq::socket_t& socket, int timeout_ms) {
  zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
  try {
    return zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms)) > 0;
  } catch (const zmq::error_t& e) {
    if (e.num() == EINTR) return false;  // a signal: the caller checks its stop flag
    throw;
  }
}

}  // namespace

std::optional<std::vector<std::string>> receive(zmq::socket_t& socket, int timeout_ms) {
  if (!readable(socket, timeout_ms)) return std::nullopt;
  std::vector<std::string> frames;
  zmq::message_t part;
  do {
    if (!socket.recv(part)) return std::nullopt;
    frames.emplace_back(part.to_string());
  } while (part.more());
  return frames;
}

std::optional<Received> receive(zmq::socket_t& socket, int timeout_ms, std::size_t envelope, std::size_t patches,
                                std::size_t chunks, std::string* user_id) {
  if (!readable(socket, timeout_ms)) return std::nullopt;
  Received r;
  MessageBound bound{2, kSignature.size() + 1};  // until the command byte (frame 1) is in
  zmq::message_t part;
  std::size_t index = 0;
  do {
    if (!socket.recv(part)) return std::nullopt;
    if (index >= envelope) {
      ++r.frames_seen;
      r.bytes_seen += part.size();
    }
    if (index == envelope + 1)
      bound = message_bound(part.size() == 1 ? *static_cast<const uint8_t*>(part.data()) : 0, patches, chunks);
    if (index >= envelope && (r.frames_seen > bound.frames || r.bytes_seen > bound.bytes)) r.over = true;
    if (!r.over) r.frames.emplace_back(part.to_string());
    // The ZAP user id rides on the frames that came through the pipe (a ROUTER's routing-id
    // frame is made locally and has none): the last frame that carries it.
    if (user_id) {
      if (index == 0) user_id->clear();
      if (const char* user = zmq_msg_gets(part.handle(), "User-Id")) *user_id = user;  // NULL without ZAP
    }
    if (index == envelope) {
      if (const char* address = zmq_msg_gets(part.handle(), "Peer-Address")) r.address = address;
      r.fd = zmq_msg_get(part.handle(), ZMQ_SRCFD);
    }
    ++index;
  } while (part.more());
  return r;
}

std::string pack(const std::vector<double>& values) {
  std::string s(values.size() * sizeof(double), '\0');
  std::memcpy(s.data(), values.data(), s.size());
  return s;
}

std::vector<double> unpack(const std::string& frame) {
  std::vector<double> v(frame.size() / sizeof(double));
  std::memcpy(v.data(), frame.data(), v.size() * sizeof(double));
  return v;
}

}  // namespace sirad::proto
