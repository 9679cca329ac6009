// sirad tests: invariants (util/check.h) are told apart from bad input: SIRAD_CHECK throws an
// InvariantError naming the source line, which no handler of sirad::Error takes.
#include "util/check.h"

#include <gtest/gtest.h>

#include <string>

#include "util/error.h"

namespace sirad {
namespace {

TEST(Invariants, HoldingCheckDoesNothing) { EXPECT_NO_THROW(SIRAD_CHECK(1 + 1 == 2, "arithmetic")); }

TEST(Invariants, BrokenCheckNamesItsLineAndConditionAndIsNoInputError) {
  bool as_error = false;
  try {
    try {
      const int patches = 3;
      SIRAD_CHECK(patches == 4, "{} patches", patches);
    } catch (const Error&) {
      as_error = true;  // what a peer's or a file's fault would be taken for
    }
    FAIL() << "no exception";
  } catch (const InvariantError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("internal error at "), std::string::npos) << what;
    EXPECT_NE(what.find("check_test.cpp:"), std::string::npos) << what;
    EXPECT_NE(what.find("3 patches (patches == 4 does not hold)"), std::string::npos) << what;
  }
  EXPECT_FALSE(as_error);
}

}  // namespace
}  // namespace sirad
