// sirad: SIRAD/1 messages over ZeroMQ sockets (frames from proto/codec.h, multipart sends).
#pragma once
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include <zmq.hpp>

#include "proto/link_model.h"

#include "proto/codec.h"

namespace sirad::proto {

// Checks a ZeroMQ endpoint as the command lines take it: tcp://HOST:PORT (PORT 1..65535; when
// binding, HOST may be * and PORT * or 0 for one the system picks), ipc://PATH or
// inproc://NAME. Throws sirad::Error naming `flag` and what is wrong.
void check_endpoint(const std::string& flag, const std::string& endpoint, bool bind);

// Socket settings of section 2 (PROTOCOL.md), before bind or connect:
//  - ZMQ_MAXMSGSIZE `max_frame_bytes`: a peer cannot make this side allocate more per frame;
//  - a send timeout: kSendTimeoutMs on a node's DEALER (its one peer), none on a ROUTER: a send
//    to a peer whose queue is full fails at once, so a peer that never reads (and rejoins,
//    and stops reading again) cannot make the coordinator's loop wait on it;
//  - ZMQ_HANDSHAKE_IVL kHandshakeMs: a connection that does not complete its ZMTP (and CURVE)
//    handshake is dropped soon;
//  - on a ROUTER, ZMQ_ROUTER_MANDATORY: a message to a peer that is gone, or whose queue is
//    full, fails the send instead of vanishing.
inline constexpr int kHandshakeMs = 3000;
inline constexpr int kSendTimeoutMs = 250;
void harden(zmq::socket_t& socket, int64_t max_frame_bytes);

// The largest frame a receiver of a run of `patches` patches takes: a chunk of all of them (24
// bytes per patch) or a header, or, `with_scene` (a node, which receives SCENE), a SCENE frame,
// whichever is larger, plus 64 KiB.
int64_t max_frame_bytes(std::size_t patches, bool with_scene = false);
// What libzmq may hold for one peer of a coordinator or farm of `patches` patches
// (PeerBytes): four of its largest messages (a node's two reports, its FINAL and what comes
// with them, each at most one largest frame of bulk and headers), plus 4 MiB.
uint64_t max_peer_bytes(std::size_t patches);

// Sends `message`, preceded by `routing_id` on a ROUTER socket. False when it could not go: the
// peer is unknown to the ROUTER (gone) or its queue was full (for the send timeout, on a DEALER).
bool send(zmq::socket_t& socket, const Message& message, const std::string* routing_id = nullptr);

// Frames as they are (a routing id first on a ROUTER socket), one multipart message; false as
// for send().
bool send_frames(zmq::socket_t& socket, const std::vector<std::string>& frames);

// One direction of a link as its sender sees it: unshaped, a message goes at once; shaped by
// a link model (link_model.h: latency, jitter, bandwidth, loss), each waits here until the
// time the model says it arrives, then goes out in order. Times are seconds on the caller's
// clock. The coordinator and the node send every message through one, shaped or not.
class ShapedLink {
 public:
  ShapedLink() = default;  // unshaped
  explicit ShapedLink(emulation::LinkModel model) : model_(model) {}
  // Sends `frames` now, or queues them until they are due. False: an unshaped send failed (a
  // queued message that cannot go is dropped and counted in failed()).
  bool send(zmq::socket_t& socket, std::vector<std::string> frames, double now);
  // Sends every message due by `now`; returns the time of the next one (infinity if none).
  double flush(zmq::socket_t& socket, double now);
  uint64_t failed() const { return failed_; }
  bool empty() const { return queue_.empty(); }
  void clear() { queue_.clear(); }

 private:
  emulation::LinkModel model_;
  std::deque<std::pair<double, std::vector<std::string>>> queue_;  // due times never decrease
  uint64_t failed_ = 0;
};

// The next multipart message, or nothing after `timeout_ms` (or when a signal interrupts the
// wait). `envelope` leading frames (a ROUTER's routing id) come first and are not counted;
// then the message is copied only while it keeps within `bound` (message_bound of its command
// byte, frame 1, with the receiver's `patches` and `chunks`). Past it, the rest is read and
// dropped uncopied, and `over` says how much there was. (libzmq holds a multipart message
// whole before any of it can be read, so the bound caps this process's copies; libzmq's own
// buffer is capped per frame by ZMQ_MAXMSGSIZE, not in frame count: PROTOCOL.md section 2.)
// `user_id`, if given, gets the message's ZAP user id (the sender's CURVE public key,
// proto/security.h), or "" without one.
struct Received {
  std::vector<std::string> frames;  // the envelope, then the message (truncated when over)
  bool over = false;                // it held more than its bound: refuse it
  std::size_t frames_seen = 0, bytes_seen = 0;  // the whole message's, envelope not counted
  std::string address;  // the sender's IP address over tcp:// (ZeroMQ's Peer-Address), else ""
  int fd = -1;          // the connection it came on (ZMQ_SRCFD, for PeerBytes::delivered), else -1
};
std::optional<Received> receive(zmq::socket_t& socket, int timeout_ms, std::size_t envelope, std::size_t patches,
                                std::size_t chunks, std::string* user_id = nullptr);
// Every frame of the next message, unbounded: for sockets whose peer is this process (the ZAP
// handler's inproc socket) and for tests; never for a peer's messages.
std::optional<std::vector<std::string>> receive(zmq::socket_t& socket, int timeout_ms);

// The bytes of doubles, and back (little-endian, as the spec's bulk frames).
std::string pack(const std::vector<double>& values);
std::vector<double> unpack(const std::string& frame);

}  // namespace sirad::proto
