// sirad: the one error type for bad input and failed operations.
// Its message is a single line naming what went wrong and where ("scene.obj:12: ...").
// Commands print it as "sirad: error: <message>" and exit non-zero.
#pragma once
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace sirad {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> f, Args&&... args) {
  throw Error(fmt::format(f, std::forward<Args>(args)...));
}

}  // namespace sirad
