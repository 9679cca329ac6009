// sirad: SIRAD/1 messages over ZeroMQ sockets (frames from proto/codec.h, multipart sends).
#pragma once
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "proto/codec.h"

namespace sirad::proto {

// Checks a ZeroMQ endpoint as the command lines take it: tcp://HOST:PORT (PORT 1..65535; when
// binding, HOST may be * and PORT * or 0 for one the system picks), ipc://PATH or
// inproc://NAME. Throws sirad::Error naming `flag` and what is wrong.
void check_endpoint(const std::string& flag, const std::string& endpoint, bool bind);

// Sends `message`, preceded by `routing_id` on a ROUTER socket.
void send(zmq::socket_t& socket, const Message& message, const std::string* routing_id = nullptr);

// Frames as they are (a routing id first on a ROUTER socket), one multipart message.
void send_frames(zmq::socket_t& socket, const std::vector<std::string>& frames);

// The sending side of an emulated link (coordinator/profile.h): messages wait here until the
// time the link model says they arrive, then go out in order. Times are seconds on the
// caller's clock.
class DelayQueue {
 public:
  void push(double due, std::vector<std::string> frames);
  // Sends every message due by `now`; returns the time of the next one (infinity if none).
  double flush(zmq::socket_t& socket, double now);
  bool empty() const { return queue_.empty(); }
  void clear() { queue_.clear(); }

 private:
  std::deque<std::pair<double, std::vector<std::string>>> queue_;  // due times never decrease
};

// Every frame of the next multipart message, or nothing after `timeout_ms` (or when a signal
// interrupts the wait).
std::optional<std::vector<std::string>> receive(zmq::socket_t& socket, int timeout_ms);

// The bytes of doubles, and back (little-endian, as the spec's bulk frames).
std::string pack(const std::vector<double>& values);
std::vector<double> unpack(const std::string& frame);

}  // namespace sirad::proto
