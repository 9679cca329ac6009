// sirad: whole files: atomic replacement (a temporary beside the target, renamed onto it) and reading.
#pragma once
#include <cstddef>
#include <cstdio>
#include <string>

namespace sirad {

// Whether commit() syncs the bytes to disk before the rename. Readers see the old file or the
// whole new one either way; `replace_only` skips the fsync for files that are only a view,
// rewritten many times a second (a run's status): a crash may leave the old one, and on a
// machine busy writing, an fsync can hold the writer's thread for seconds.
enum class Durability { synced, replace_only };

// Writes "<path>.tmp.<pid>.<n>" and, on commit(), flushes, syncs and renames it onto `path`, so
// `path` is either untouched or complete. Destroyed uncommitted (an error on the way), it removes
// the temporary. Every failure throws sirad::Error "cannot write <path>: <reason>".
class AtomicFile {
 public:
  explicit AtomicFile(std::string path, Durability durability = Durability::synced);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::string& path() const { return path_; }
  std::FILE* stream() const { return file_; }
  void write(const void* data, std::size_t size);
  void commit();

  // Throws "cannot write <path>: <reason>"; the _errno form uses strerror(error).
  [[noreturn]] void fail(const std::string& reason) const;
  [[noreturn]] void fail_errno(int error) const;

 private:
  std::string path_, temp_;
  Durability durability_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

// Replaces `path` atomically with `text`.
void write_file_atomic(const std::string& path, const std::string& text, Durability durability = Durability::synced);

// The whole of the regular file at `path`, at most `max_bytes`, or one error starting with
// `label`: "no such file", "is a directory, not a file", "not a regular file" (a FIFO or a
// device: never opened for a blocking read), "cannot open (REASON)", or `too_large` where it
// holds more than `max_bytes` (checked before reading and while reading).
std::string read_regular_file(const std::string& path, const std::string& label, std::size_t max_bytes,
                              const std::string& too_large);

// The whole of the file at `path` (a profile, a key file, a checkpoint), at most `max_bytes`,
// or one error: "PATH: cannot read the WHAT: REASON" (no such file, not a regular file, ...,
// or "larger than N KiB or MiB (no WHAT is)").
std::string read_file_whole(const std::string& path, const std::string& what, std::size_t max_bytes);

}  // namespace sirad
