// sirad: numbers read from text a user or a file gives (flags, a run's settings): the whole text
// one number, finite, within its bounds; else a sirad::Error that says what is wrong without
// naming where it came from (the caller names the flag).
#pragma once
#include <cstdint>
#include <string>

namespace sirad {

int64_t integer_in(const std::string& text, int64_t lo, int64_t hi);  // "must be in [lo, hi] (got TEXT)"
uint64_t unsigned_integer(const std::string& text);                     // any value of 64 bits
double real_in(const std::string& text, double lo, double hi);         // "must be in [lo, hi] (got TEXT)"
double positive_real(const std::string& text);                          // "must be greater than 0 (got TEXT)"
double non_negative_real(const std::string& text);                      // "must be 0 or more (got TEXT)"

}  // namespace sirad
