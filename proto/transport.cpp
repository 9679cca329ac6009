// sirad: SIRAD/1 over ZeroMQ: multipart send and receive with a timeout.
#include "proto/transport.h"

#include <cerrno>
#include <cstring>

namespace sirad::proto {

void send(zmq::socket_t& socket, const Message& message, const std::string* routing_id) {
  std::vector<std::string> frames = encode(message);
  if (routing_id) socket.send(zmq::buffer(*routing_id), zmq::send_flags::sndmore);
  for (std::size_t i = 0; i < frames.size(); ++i)
    socket.send(zmq::buffer(frames[i]), i + 1 < frames.size() ? zmq::send_flags::sndmore : zmq::send_flags::none);
}

std::optional<std::vector<std::string>> receive(zmq::socket_t& socket, int timeout_ms) {
  zmq::pollitem_t item{socket.handle(), 0, ZMQ_POLLIN, 0};
  try {
    if (zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms)) == 0) return std::nullopt;
  } catch (const zmq::error_t& e) {
    if (e.num() == EINTR) return std::nullopt;  // a signal: the caller checks its stop flag
    throw;
  }
  std::vector<std::string> frames;
  zmq::message_t part;
  do {
    if (!socket.recv(part)) return std::nullopt;
    frames.emplace_back(part.to_string());
  } while (part.more());
  return frames;
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
