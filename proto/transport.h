// sirad: SIRAD/1 messages over ZeroMQ sockets (frames from proto/codec.h, multipart sends).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "proto/codec.h"

namespace sirad::proto {

// Sends `message`, preceded by `routing_id` on a ROUTER socket.
void send(zmq::socket_t& socket, const Message& message, const std::string* routing_id = nullptr);

// Every frame of the next multipart message, or nothing after `timeout_ms` (or when a signal
// interrupts the wait).
std::optional<std::vector<std::string>> receive(zmq::socket_t& socket, int timeout_ms);

// The bytes of doubles, and back (little-endian, as the spec's bulk frames).
std::string pack(const std::vector<double>& values);
std::vector<double> unpack(const std::string& frame);

}  // namespace sirad::proto
