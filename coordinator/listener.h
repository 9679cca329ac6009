// sirad: the bound ROUTER socket a coordinator (one run, or a farm) serves nodes on: the ZAP
// handler first (libzmq admits everyone without one), frames bounded for the run's patches, what
// libzmq may hold per peer bounded (proto/peer_bytes.h), CURVE when keys are given; the bound
// endpoint logged and written for scripts.
#pragma once
#include <cstddef>
#include <optional>
#include <string>

#include <zmq.hpp>

#include "proto/peer_bytes.h"
#include "proto/security.h"

namespace sirad::coordinator {

// --curve-secret and --allow (checked against --listen and --insecure first): the key pair and
// the admitted node keys, or none over inproc or with --insecure.
struct ServerKeys {
  std::optional<proto::KeyPair> keys;
  proto::AllowList allow;
};
ServerKeys server_keys(const std::string& listen, const std::string& curve_secret, const std::string& allow_file, bool insecure);

// The socket bound to `listen`, for up to `max_patches` patches; `what` (the run or the farm)
// goes into the log line that names the endpoint, which `endpoint_file` (if named) receives.
struct Listener {
  std::optional<proto::ZapHandler> zap;
  zmq::socket_t router;
  std::optional<proto::PeerBytes> bytes;  // what libzmq holds per peer, bounded
  std::string bound;
  Listener(zmq::context_t& context, const std::string& listen, const std::optional<proto::KeyPair>& keys,
           const proto::AllowList& allow, std::size_t max_patches, bool insecure, const std::string& endpoint_file,
           const std::string& what);
};

}  // namespace sirad::coordinator
