// sirad: atomic file replacement (temporary file beside the target, fsync, rename).
#include "core/atomic_file.h"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <utility>

#include <fcntl.h>
#include <unistd.h>

#include "core/error.h"

namespace sirad {

namespace {
std::atomic<unsigned> temp_counter{0};
}  // namespace

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  // Step 1: a temporary name unique to this process and this writer, in the target's directory
  // (so the final rename stays within one file system).
  temp_ = fmt::format("{}.tmp.{}.{}", path_, ::getpid(), temp_counter.fetch_add(1));
  const int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) fail_errno(errno);
  file_ = ::fdopen(fd, "wb");
  if (file_ == nullptr) {
    const int error = errno;
    ::close(fd);
    std::remove(temp_.c_str());
    fail_errno(error);
  }
}

AtomicFile::~AtomicFile() {
  if (committed_) return;
  if (file_ != nullptr) std::fclose(file_);
  std::remove(temp_.c_str());
}

void AtomicFile::write(const void* data, std::size_t size) {
  if (size != 0 && std::fwrite(data, 1, size, file_) != size) fail_errno(errno);
}

void AtomicFile::commit() {
  // Step 2: every byte on disk (a failed buffered write shows in ferror), then the rename.
  if (std::ferror(file_)) fail("write error");
  if (std::fflush(file_) != 0 || ::fsync(::fileno(file_)) != 0) fail_errno(errno);
  const int closed = std::fclose(file_);
  file_ = nullptr;
  if (closed != 0) fail_errno(errno);
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) fail_errno(errno);
  committed_ = true;
}

void AtomicFile::fail(const std::string& reason) const {
  sirad::fail("cannot write {}: {}", path_, reason);
}

void AtomicFile::fail_errno(int error) const { fail(std::strerror(error)); }

void write_file_atomic(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.write(text.data(), text.size());
  f.commit();
}

std::string read_file_whole(const std::string& path, const std::string& what, std::size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot read the {}: {}", path, what, std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (max_bytes > 0 && text.str().size() > max_bytes)
    fail("{}: not a {} (over {})", path, what,
         max_bytes % (1 << 20) == 0 ? fmt::format("{} MiB", max_bytes >> 20) : fmt::format("{} KiB", max_bytes >> 10));
  return std::move(text).str();
}

}  // namespace sirad
