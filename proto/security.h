// sirad: CURVE authentication and encryption for SIRAD/1 over TCP (PROTOCOL.md section 7).
// The coordinator is a CURVE server with its own key pair; every node is a CURVE client with
// its own key pair and the coordinator's public key. A ZAP handler in the coordinator's process
// admits only the node public keys of an allow-list file. Key files follow the ZeroMQ
// certificate format (czmq's zcert: `metadata` and `curve` sections, Z85 keys), so keys made by
// other ZeroMQ tools work too.
#pragma once
#include <atomic>
#include <map>
#include <string>
#include <thread>

#include <zmq.hpp>

namespace sirad::proto {

struct KeyPair {
  std::string public_key;  // Z85, 40 characters
  std::string secret_key;  // Z85, 40 characters (empty for a public key alone)
};

// A fresh key pair (zmq_curve_keypair). Throws sirad::Error where libzmq has no CURVE.
KeyPair generate_keypair();

// Writes `base`.key (the public key) and `base`.key_secret (both keys, mode 0600), each
// atomically; refuses to overwrite either.
void write_keypair(const std::string& base, const KeyPair& keys);

// A secret key file (`base`.key_secret as write_keypair writes it). Refused, with one line
// naming the file: a file others may read or write (any of mode 077; chmod 600), a missing or
// malformed key, a public key that does not match the secret one.
KeyPair load_secret_key(const std::string& path);

// The public key of a key file (.key or .key_secret), or the file holding just a Z85 key.
std::string load_public_key(const std::string& path);

// The node keys a coordinator admits: one per line, a Z85 public key (40 characters) and an
// optional name after it; blank lines and lines starting with # are skipped. A malformed line
// or a repeated key is an error naming the file and line. Maps key -> name ("" if none).
using AllowList = std::map<std::string, std::string>;
AllowList load_allow_list(const std::string& path);

// Makes `socket` a CURVE server with `keys` (before bind); the ZAP domain "sirad".
void make_curve_server(zmq::socket_t& socket, const KeyPair& keys);
// Makes `socket` a CURVE client with its own `keys`, trusting `server_public_key` (before connect).
void make_curve_client(zmq::socket_t& socket, const KeyPair& keys, const std::string& server_public_key);

// The ZAP handler (RFC 27) of `context`: answers every handshake of a CURVE socket in that
// context, admitting exactly the keys of `allow` (user id: the key's Z85 text, so the
// coordinator sees who sent each message as the "User-Id" property) and logging each refusal
// with the peer's address. Must exist before the server socket binds (libzmq admits everyone
// when no handler is bound); throws sirad::Error if the ZAP endpoint is taken. Stops with
// the object.
// The command lines' rule: over tcp:// every socket is CURVE (`has_keys`) unless `insecure`
// asks for none; over ipc:// and inproc:// keys are optional. Keys and --insecure together are
// refused too. Throws sirad::Error naming `program`'s flags.
void check_security(const std::string& endpoint, bool has_keys, bool insecure, const std::string& key_flags);

// The one line a program logs on start without CURVE over TCP (after its name).
std::string insecure_warning(const std::string& endpoint);

class ZapHandler {
 public:
  ZapHandler(zmq::context_t& context, AllowList allow);
  ~ZapHandler();
  ZapHandler(const ZapHandler&) = delete;
  ZapHandler& operator=(const ZapHandler&) = delete;
  uint64_t refused() const { return refused_; }

 private:
  void serve();
  zmq::socket_t socket_;
  AllowList allow_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> refused_{0};
  std::thread thread_;
};

}  // namespace sirad::proto
