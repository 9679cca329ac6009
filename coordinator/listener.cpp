// sirad: the bound ROUTER socket of a coordinator (see listener.h).
#include "coordinator/listener.h"

#include <fmt/format.h>

#include "engine/version.h"
#include "proto/transport.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/log.h"

namespace sirad::coordinator {

ServerKeys server_keys(const std::string& listen, const std::string& curve_secret, const std::string& allow_file, bool insecure) {
  proto::check_endpoint("--listen", listen, true);
  proto::check_security(listen, !curve_secret.empty(), insecure, "--curve-secret and --allow");
  ServerKeys k;
  if (!curve_secret.empty()) {
    k.keys = proto::load_secret_key(curve_secret);
    k.allow = proto::load_allow_list(allow_file);
    if (k.allow.empty()) fail("{}: the allow list admits no node", allow_file);
  }
  return k;
}

Listener::Listener(zmq::context_t& context, const std::string& listen, const std::optional<proto::KeyPair>& keys,
                   const proto::AllowList& allow, std::size_t max_patches, bool insecure, const std::string& endpoint_file,
                   const std::string& what) {
  if (keys) zap.emplace(context, allow);
  router = zmq::socket_t(context, zmq::socket_type::router);
  router.set(zmq::sockopt::linger, 0);
  proto::harden(router, proto::max_frame_bytes(max_patches));
  const uint64_t per_peer = proto::max_peer_bytes(max_patches);
  bytes.emplace(context, router, per_peer, [per_peer](const std::string& address, uint64_t held) {
    logging::write(logging::Level::warn, "sirad-coordinator",
                   fmt::format("{}: connection shut: libzmq held {} bytes of its unread messages, over the bound of {}", address,
                               held, per_peer),
                   {{"event", "peer bytes"}, {"address", address}, {"held", held}});
  });
  if (keys) proto::make_curve_server(router, *keys);
  try {
    router.bind(listen);
  } catch (const zmq::error_t& e) {
    fail("--listen {}: {}", listen, e.what());
  }
  bound = router.get(zmq::sockopt::last_endpoint);
  logging::write(logging::Level::info, "sirad-coordinator",
                 fmt::format("{}; listening on {}{}", what, bound, keys ? fmt::format(" (CURVE, {} node keys allowed)", allow.size()) : ""),
                 {{"event", "listening"}, {"endpoint", bound}, {"version", kVersion}});
  if (insecure) logging::write(logging::Level::warn, "sirad-coordinator", proto::insecure_warning(bound), {{"event", "insecure"}});
  if (!endpoint_file.empty()) write_file_atomic(endpoint_file, bound);
}

}  // namespace sirad::coordinator
