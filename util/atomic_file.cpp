// sirad: atomic file replacement (temporary file beside the target, fsync, rename).
#include "util/atomic_file.h"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "util/error.h"

namespace sirad {

namespace {
std::atomic<unsigned> temp_counter{0};
}  // namespace

AtomicFile::AtomicFile(std::string path, Durability durability) : path_(std::move(path)), durability_(durability) {
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
  if (std::fflush(file_) != 0 || (durability_ == Durability::synced && ::fsync(::fileno(file_)) != 0)) fail_errno(errno);
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

void write_file_atomic(const std::string& path, const std::string& text, Durability durability) {
  AtomicFile f(path, durability);
  f.write(text.data(), text.size());
  f.commit();
}

std::string read_regular_file(const std::string& path, const std::string& label, std::size_t max_bytes,
                              const std::string& too_large) {
  // O_NONBLOCK: opening a FIFO with no writer returns at once (and is refused below).
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) fail("{}: no such file", label);
    fail("{}: cannot open ({})", label, std::strerror(errno));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) fail("{}: cannot access ({})", label, std::strerror(errno));
  if (S_ISDIR(st.st_mode)) fail("{}: is a directory, not a file", label);
  if (!S_ISREG(st.st_mode)) fail("{}: not a regular file", label);
  if (static_cast<uint64_t>(st.st_size) > max_bytes) fail("{}: {}", label, too_large);
  // Read what is there, up to the bound (the file may grow while it is read).
  std::string text;
  text.reserve(static_cast<std::size_t>(st.st_size));
  std::vector<char> chunk(1 << 16);
  for (;;) {
    const ssize_t n = ::read(fd, chunk.data(), chunk.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail("{}: read error ({})", label, std::strerror(errno));
    if (n == 0) break;
    if (text.size() + static_cast<std::size_t>(n) > max_bytes) fail("{}: {}", label, too_large);
    text.append(chunk.data(), static_cast<std::size_t>(n));
  }
  return text;
}

std::string read_file_whole(const std::string& path, const std::string& what, std::size_t max_bytes) {
  const std::string size = max_bytes % (1 << 20) == 0 ? fmt::format("{} MiB", max_bytes >> 20) : fmt::format("{} KiB", max_bytes >> 10);
  return read_regular_file(path, fmt::format("{}: cannot read the {}", path, what), max_bytes,
                           fmt::format("larger than {} (no {} is)", size, what));
}

}  // namespace sirad
