// sirad tests: the fixture of the command-line tests: the programs run in a folder of the test's
// own, their exit status and output captured, and the check that a failure is one clear line
// that leaves no file behind.
#pragma once
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/test_folder.h"

namespace sirad::test {

namespace fs = std::filesystem;

struct Outcome {
  int status;
  std::string out, err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = sirad::test::fresh_test_folder("sirad_cli");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs `sirad ARGS` in the test's directory; captures stdout, stderr and the exit status.
  Outcome sirad(const std::string& args, const std::string& env = "") { return program(SIRAD_BINARY, args, env); }

  // Runs `binary ARGS` as sirad() does.
  Outcome program(const std::string& binary, const std::string& args, const std::string& env = "") {
    std::string out = (dir_ / "stdout.txt").string(), err = (dir_ / "stderr.txt").string();
    std::string cmd = "cd '" + dir_.string() + "' && " + env + " '" + binary + "' " + args + " >'" + out +
                      "' 2>'" + err + "' </dev/null";
    int raw = std::system(cmd.c_str());
    Outcome r{WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), slurp(out), slurp(err)};
    fs::remove(out);
    fs::remove(err);
    return r;
  }

  static std::string slurp(const std::string& path) {
    std::ifstream in(path);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  void write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }

  // No output or temporary file of any kind in the directory.
  void expect_no_outputs() {
    for (const auto& e : fs::directory_iterator(dir_)) {
      std::string n = e.path().filename().string();
      EXPECT_FALSE(n.find(".exr") != std::string::npos || n.find(".png") != std::string::npos ||
                   n.find(".ply") != std::string::npos || n.find(".tmp") != std::string::npos)
          << "left behind: " << n;
    }
  }

  // A failure: non-zero exit, exactly one line on stderr starting "PROGRAM: error:" and naming
  // `what`, nothing written.
  void expect_error(const Outcome& r, const std::string& what, const std::string& program = "sirad") {
    EXPECT_NE(r.status, 0);
    EXPECT_LT(r.status, 128) << "crashed";
    EXPECT_EQ(r.err.rfind(program + ": error:", 0), 0u) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << "expected '" << what << "' in: " << r.err;
    expect_no_outputs();
  }

  fs::path dir_;
};

}  // namespace sirad::test
