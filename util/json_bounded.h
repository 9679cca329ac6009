// sirad: JSON from outside the process (files, the network) read within bounds: its size and
// how deep its arrays and objects nest are checked on the text, before any parser builds from
// it (a parser that recurses, like tinygltf's conversion of `extras`, overflows the stack on
// 20,000 levels; nlohmann's values of a 1 GiB text take several GiB). glTF, the farm's API, job
// and status files need fewer than 10 levels.
#pragma once
#include <cstddef>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace sirad {

inline constexpr std::size_t kMaxJsonDepth = 64;

// How deep `text`'s arrays and objects nest (brackets outside strings), counted up to
// `limit` + 1: the scan stops once it passes `limit`. Malformed text is the parser's to refuse.
std::size_t json_depth(std::string_view text, std::size_t limit);

// One error, "WHAT: JSON nested deeper than N levels", where `text` nests deeper than `max_depth`.
void check_json_depth(std::string_view text, const std::string& what, std::size_t max_depth = kMaxJsonDepth);

// `text` parsed by nlohmann::json after its size (at most `max_bytes`: "WHAT: JSON larger than
// N bytes") and depth are checked; text that is not JSON throws nlohmann's parse_error as
// json::parse does, for the caller to word.
nlohmann::json parse_json_bounded(std::string_view text, const std::string& what, std::size_t max_bytes,
                                  std::size_t max_depth = kMaxJsonDepth);

}  // namespace sirad
