// sirad: numbers read from text (see numbers.h).
#include "util/numbers.h"

#include <charconv>
#include <cmath>
#include <cstdlib>

#include "util/error.h"

namespace sirad {

namespace {

// The whole text as a finite double (strtod's syntax: decimal, exponent, hex).
double finite_real(const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v)) fail("'{}' is not a finite number", text);
  return v;
}

}  // namespace

int64_t integer_in(const std::string& text, int64_t lo, int64_t hi) {
  int64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) fail("'{}' is not a whole number", text);
  if (v < lo || v > hi) fail("must be in [{}, {}] (got {})", lo, hi, text);
  return v;
}

uint64_t unsigned_integer(const std::string& text) {
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) fail("'{}' is not a whole number in [0, 2^64)", text);
  return v;
}

double real_in(const std::string& text, double lo, double hi) {
  const double v = finite_real(text);
  if (!(v >= lo && v <= hi)) fail("must be in [{}, {}] (got {})", lo, hi, text);
  return v;
}

double positive_real(const std::string& text) {
  const double v = finite_real(text);
  if (!(v > 0)) fail("must be greater than 0 (got {})", text);
  return v;
}

double non_negative_real(const std::string& text) {
  const double v = finite_real(text);
  if (!(v >= 0)) fail("must be 0 or more (got {})", text);
  return v;
}

}  // namespace sirad
