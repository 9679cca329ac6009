// sirad: invariants, what the code itself guarantees. SIRAD_CHECK(condition, format, args...)
// throws InvariantError when the condition does not hold: a bug in sirad, never a fault of a
// peer, a file or a flag. InvariantError is not a sirad::Error, so no handler of bad input takes
// it for one (the coordinator does not blame the node whose message it was handling, a node
// does not answer its coordinator with ERROR): it ends the run, which fails naming the source
// line; a farm fails that job and goes on. Bad input is sirad::Error (util/error.h).
#pragma once
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace sirad {

class InvariantError : public std::logic_error {
 public:
  explicit InvariantError(const std::string& what) : std::logic_error(what) {}
};

namespace detail {
[[noreturn]] inline void invariant_failed(const char* file, int line, const char* condition, const std::string& message) {
  throw InvariantError(fmt::format("internal error at {}:{}: {} ({} does not hold)", file, line, message, condition));
}
}  // namespace detail

}  // namespace sirad

#define SIRAD_CHECK(condition, ...)                                                                  \
  do {                                                                                               \
    if (!(condition)) [[unlikely]]                                                                   \
      ::sirad::detail::invariant_failed(__FILE__, __LINE__, #condition, ::fmt::format(__VA_ARGS__)); \
  } while (false)
