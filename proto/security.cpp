// sirad: CURVE key files, the allow list and the ZAP handler (see security.h).
#include "proto/security.h"

#include <sys/stat.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "proto/transport.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::proto {

namespace {

constexpr std::size_t kZ85KeyChars = 40;

bool is_z85_key(const std::string& s) {
  if (s.size() != kZ85KeyChars) return false;
  uint8_t raw[32];
  return zmq_z85_decode(raw, s.c_str()) != nullptr;
}

// The value of `key = "..."` in a certificate (czmq's ZPL), if present; a malformed value is
// an error naming the file and line.
std::optional<std::string> cert_value(const std::string& text, const std::string& key, const std::string& path) {
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::size_t at = line.find_first_not_of(" \t");
    if (at == std::string::npos || line.compare(at, key.size(), key) != 0) continue;
    std::size_t eq = line.find('=', at + key.size());
    if (eq == std::string::npos || line.find_first_not_of(" \t", at + key.size()) != eq) continue;
    std::size_t open = line.find('"', eq), close = open == std::string::npos ? open : line.find('"', open + 1);
    if (open == std::string::npos || close == std::string::npos) fail("{}:{}: {} is not a quoted Z85 key", path, number, key);
    std::string value = line.substr(open + 1, close - open - 1);
    if (!is_z85_key(value)) fail("{}:{}: {} is not a Z85 CURVE key (40 characters)", path, number, key);
    return value;
  }
  return std::nullopt;
}

std::string certificate(const KeyPair& keys, bool secret) {
  std::string out = fmt::format(
      "#   sirad CURVE {} key ({})\n"
      "{}"
      "\nmetadata\ncurve\n    public-key = \"{}\"\n",
      secret ? "secret" : "public", secret ? "mode 0600; never share it" : "give it to the other side",
      secret ? "#   DO NOT PROVIDE THIS FILE TO OTHER USERS nor change its permissions.\n" : "", keys.public_key);
  if (secret) out += fmt::format("    secret-key = \"{}\"\n", keys.secret_key);
  return out;
}

}  // namespace

KeyPair generate_keypair() {
  if (!zmq_has("curve")) fail("this libzmq was built without CURVE (libsodium): no keys, no encryption");
  char pub[41], sec[41];
  if (zmq_curve_keypair(pub, sec) != 0) fail("cannot make a CURVE key pair: {}", zmq_strerror(zmq_errno()));
  return {pub, sec};
}

void write_keypair(const std::string& base, const KeyPair& keys) {
  const std::string pub = base + ".key", sec = base + ".key_secret";
  for (const std::string& p : {pub, sec})
    if (std::filesystem::exists(p)) fail("{}: exists; sirad keygen never overwrites a key", p);
  {
    AtomicFile f(sec);
    if (::fchmod(fileno(f.stream()), 0600) != 0) f.fail_errno(errno);
    std::string text = certificate(keys, true);
    f.write(text.data(), text.size());
    f.commit();
  }
  AtomicFile f(pub);
  std::string text = certificate(keys, false);
  f.write(text.data(), text.size());
  f.commit();
}

KeyPair load_secret_key(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail("{}: cannot read the secret key file", path);
  if ((st.st_mode & 077) != 0)
    fail("{}: secret key file has mode {:04o}; others may read it (chmod 600 {})", path, st.st_mode & 07777, path);
  std::string text = read_file_whole(path, "secret key file", 64 * 1024);
  std::optional<std::string> pub = cert_value(text, "public-key", path), sec = cert_value(text, "secret-key", path);
  if (!sec) fail("{}: no secret-key in the file (is it the .key_secret file?)", path);
  if (!pub) fail("{}: no public-key in the file", path);
  char derived[41];
  if (zmq_curve_public(derived, sec->c_str()) != 0 || *pub != derived)
    fail("{}: the public key does not belong to the secret key", path);
  return {*pub, *sec};
}

std::string load_public_key(const std::string& path) {
  std::string text = read_file_whole(path, "public key file", 64 * 1024);
  if (std::optional<std::string> pub = cert_value(text, "public-key", path)) return *pub;
  std::string trimmed;
  for (char c : text)
    if (!std::isspace(static_cast<unsigned char>(c))) trimmed += c;
  if (is_z85_key(trimmed)) return trimmed;
  fail("{}: no public-key in the file (a .key file from sirad keygen, or one Z85 key)", path);
}

AllowList load_allow_list(const std::string& path) {
  std::string text = read_file_whole(path, "allow list", 64 * 1024);
  AllowList out;
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream words(line);
    std::string key, name;
    if (!(words >> key) || key[0] == '#') continue;
    std::getline(words >> std::ws, name);
    if (!is_z85_key(key)) fail("{}:{}: '{}' is not a Z85 CURVE public key (40 characters)", path, number, key.substr(0, 48));
    if (!out.emplace(key, name).second) fail("{}:{}: key listed twice", path, number);
  }
  return out;
}

void make_curve_server(zmq::socket_t& socket, const KeyPair& keys) {
  socket.set(zmq::sockopt::zap_domain, "sirad");
  socket.set(zmq::sockopt::curve_server, 1);
  socket.set(zmq::sockopt::curve_secretkey, keys.secret_key);
}

void make_curve_client(zmq::socket_t& socket, const KeyPair& keys, const std::string& server_public_key) {
  socket.set(zmq::sockopt::curve_serverkey, server_public_key);
  socket.set(zmq::sockopt::curve_publickey, keys.public_key);
  socket.set(zmq::sockopt::curve_secretkey, keys.secret_key);
}

void check_security(const std::string& endpoint, bool has_keys, bool insecure, const std::string& key_flags) {
  if (has_keys && insecure) fail("--insecure with {}: choose one", key_flags);
  if (endpoint.rfind("tcp://", 0) == 0 && !has_keys && !insecure)
    fail("{} is TCP: give {} (make keys with `sirad keygen NAME`), or ask for no authentication and no encryption "
         "with --insecure",
         endpoint, key_flags);
}

std::string insecure_warning(const std::string& endpoint) {
  return fmt::format("WARNING: --insecure: {} runs without authentication or encryption; anyone who can reach it "
                     "can join the run and inject radiosity",
                     endpoint);
}

ZapHandler::ZapHandler(zmq::context_t& context, AllowList allow)
    : socket_(context, zmq::socket_type::rep), allow_(std::move(allow)) {
  socket_.set(zmq::sockopt::linger, 0);
  try {
    socket_.bind("inproc://zeromq.zap.01");
  } catch (const zmq::error_t& e) {
    fail("cannot start the ZAP handler (inproc://zeromq.zap.01): {}", e.what());
  }
  thread_ = std::thread([this] { serve(); });
}

ZapHandler::~ZapHandler() {
  stop_ = true;
  thread_.join();
}

// RFC 27: request = version, request id, domain, address, routing id, mechanism, credentials;
// reply = version, request id, status code, status text, user id, metadata.
void ZapHandler::serve() {
  while (!stop_) {
    std::optional<std::vector<std::string>> request = receive(socket_, 100);
    if (!request) continue;
    std::vector<std::string>& r = *request;
    std::string code = "400", text = "malformed ZAP request", user;
    if (r.size() >= 6 && r[0] == "1.0") {
      const std::string& mechanism = r[5];
      if (mechanism == "CURVE" && r.size() == 7 && r[6].size() == 32) {
        char z85[41];
        zmq_z85_encode(z85, reinterpret_cast<const uint8_t*>(r[6].data()), 32);
        if (allow_.count(z85)) {
          code = "200", text = "OK", user = z85;
        } else {
          text = "key not in the allow list";
          ++refused_;
          std::fprintf(stderr, "sirad-coordinator: refused a node from %s: its key %s is not in the allow list\n",
                       r[3].c_str(), z85);
        }
      } else {
        text = "only CURVE is admitted";
        ++refused_;
        std::fprintf(stderr, "sirad-coordinator: refused a %s connection from %s: only CURVE is admitted\n",
                     mechanism.c_str(), r[3].c_str());
      }
    }
    send_frames(socket_, {"1.0", r.size() >= 2 ? r[1] : std::string(), code, text, user, std::string()});
  }
}

}  // namespace sirad::proto
