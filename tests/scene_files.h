// sirad tests: a fixture for scene files written by a test into a folder of its own, and the
// check that a file is refused with one line naming it.
#pragma once
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "scene/import.h"
#include "tests/test_folder.h"
#include "util/error.h"

namespace sirad::test {

namespace fs = std::filesystem;

class SceneFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fresh_test_folder("sirad_scene_files");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
    return (dir_ / name).string();
  }
  // `text` written as `name` is refused with one sirad::Error of one line naming the file;
  // returns the message ("" when it was accepted).
  std::string expect_refused(const std::string& name, const std::string& text) {
    try {
      load_scene(write(name, text));
      ADD_FAILURE() << "accepted";
      return "";
    } catch (const Error& e) {
      std::string m = e.what();
      EXPECT_EQ(m.find('\n'), std::string::npos) << m;
      EXPECT_NE(m.find(name), std::string::npos) << m;
      return m;
    }
  }
  fs::path dir_;
};

}  // namespace sirad::test
