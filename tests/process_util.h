// sirad tests: child processes (the real binaries) and their files.
#pragma once
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace sirad::test {

namespace fs = std::filesystem;

// The longest any test waits for an event of a child process (an exit, a file, a log line)
// before it calls it hung, and the --timeout its coordinators run under. Every wait ends at its
// event; this bound only turns a hang into a failure, so it is far beyond what the slowest
// event takes on a loaded machine (the suite is run with two CPU burners beside ctest -j 2).
inline constexpr double kHangS = 900;
inline const char* kHangTimeout = "900";

// A child process, killed if still running when it goes out of scope.
class Child {
 public:
  Child(std::vector<std::string> args, const fs::path& log) {
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~Child() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  // Exit status, or -1 if it has not exited within `seconds`.
  int wait(double seconds) {
    if (pid_ <= 0) return 127;  // never started (posix_spawn failed): nothing to wait for
    auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (exited_) return status_;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        return status_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }
  void terminate() { ::kill(pid_, SIGTERM); }
  void kill9() { ::kill(pid_, SIGKILL); }
  void pause() { ::kill(pid_, SIGSTOP); }
  void interrupt() { ::kill(pid_, SIGINT); }
  void resume() { ::kill(pid_, SIGCONT); }
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  int status_ = -1;
};

// Waits for the file `path` that `writer` writes (an endpoint file, say): true once it exists,
// false when `writer` exited without it. The cap is for a hung child, far beyond any load.
inline bool wait_for_file(const fs::path& path, Child& writer, double seconds = kHangS) {
  auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!fs::exists(path)) {
    if (writer.wait(0.02) >= 0 || std::chrono::steady_clock::now() > until) return fs::exists(path);
  }
  return true;
}

// The path of `program` on the PATH (posix_spawn does not search it), or "" when it is not there.
inline std::string on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  for (std::size_t at = 0; at <= dirs.size();) {
    std::size_t end = dirs.find(':', at);
    if (end == std::string::npos) end = dirs.size();
    fs::path candidate = fs::path(dirs.substr(at, end - at)) / program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    at = end + 1;
  }
  return "";
}

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Waits until `event` holds, polling every 25 ms for at most `seconds` (a bound against a hung
// child, not a timing assumption: every event waited for must happen). Returns whether it did.
template <typename F>
bool wait_until(F event, double seconds = kHangS) {
  for (int i = 0; i < seconds * 40; ++i) {
    if (event()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return event();
}

// `sirad keygen NAME` in `dir` (the binary `sirad`); returns the allow-list line it prints, or
// "" when it printed none.
inline std::string keygen(const std::string& sirad, const fs::path& dir, const std::string& name) {
  Child k({sirad, "keygen", (dir / name).string()}, dir / (name + ".keygen.log"));
  if (k.wait(kHangS) != 0) return "";
  std::string log = slurp(dir / (name + ".keygen.log"));
  auto at = log.find("allow-list line: ");
  return at == std::string::npos ? "" : log.substr(at + 17, log.find('\n', at) - at - 17);
}

}  // namespace sirad::test
