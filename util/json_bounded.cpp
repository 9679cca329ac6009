// sirad: JSON read within bounds on size and nesting (see json_bounded.h).
#include "util/json_bounded.h"

#include <algorithm>

#include "util/error.h"

namespace sirad {

std::size_t json_depth(std::string_view text, std::size_t limit) {
  std::size_t depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) return deepest;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

void check_json_depth(std::string_view text, const std::string& what, std::size_t max_depth) {
  if (json_depth(text, max_depth) > max_depth) fail("{}: JSON nested deeper than {} levels", what, max_depth);
}

nlohmann::json parse_json_bounded(std::string_view text, const std::string& what, std::size_t max_bytes, std::size_t max_depth) {
  if (text.size() > max_bytes) fail("{}: JSON larger than {} bytes", what, max_bytes);
  check_json_depth(text, what, max_depth);
  return nlohmann::json::parse(text);
}

}  // namespace sirad
