// sirad tests: a folder of each test's own, for the files it writes.
#pragma once
#include <unistd.h>

#include <filesystem>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

namespace sirad::test {

// TMP/PREFIX_PID_TEST, emptied and made: the running test's own folder (ctest -j runs tests
// side by side, each its own process).
inline std::filesystem::path fresh_test_folder(const std::string& prefix) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      fmt::format("{}_{}_{}", prefix, ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace sirad::test
