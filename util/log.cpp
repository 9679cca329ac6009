// sirad: the operator's log (see log.h).
#include "util/log.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <mutex>

#include <fmt/format.h>

#include "util/error.h"

namespace sirad::logging {

namespace {

std::mutex mutex;
Level current_level = Level::info;
Format current_format = Format::text;

const char* name_of(Level level) {
  switch (level) {
    case Level::error: return "error";
    case Level::warn: return "warn";
    case Level::info: return "info";
    case Level::debug: return "debug";
  }
  return "info";
}

}  // namespace

Level parse_level(const std::string& name, const std::string& flag) {
  for (Level l : {Level::error, Level::warn, Level::info, Level::debug})
    if (name == name_of(l)) return l;
  fail("{}: '{}' is not a log level (error, warn, info, debug)", flag, name);
}

Format parse_format(const std::string& name, const std::string& flag) {
  if (name == "text") return Format::text;
  if (name == "json") return Format::json;
  fail("{}: '{}' is not a log format (text, json)", flag, name);
}

void configure(Level level, Format format) {
  std::lock_guard lock(mutex);
  current_level = level;
  current_format = format;
}

bool enabled(Level level) {
  std::lock_guard lock(mutex);
  return level <= current_level;
}

std::string json_line(double unix_seconds, Level level, const std::string& who, const std::string& message,
                      const nlohmann::json& fields) {
  const std::time_t whole = static_cast<std::time_t>(std::floor(unix_seconds));
  std::tm utc{};
  gmtime_r(&whole, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &utc);
  const int ms = std::clamp(static_cast<int>((unix_seconds - static_cast<double>(whole)) * 1000), 0, 999);
  nlohmann::json line = {{"time", fmt::format("{}.{:03d}Z", stamp, ms)}, {"level", name_of(level)}, {"who", who}, {"message", message}};
  if (fields.is_object())
    for (const auto& [key, value] : fields.items())
      if (!line.contains(key)) line[key] = value;
  // Names and messages from peers may hold any bytes: replaced, never a broken line.
  return line.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void write(Level level, const std::string& who, const std::string& message, const nlohmann::json& fields) {
  std::lock_guard lock(mutex);
  if (level > current_level) return;
  std::string line;
  if (current_format == Format::json) {
    const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    line = json_line(now, level, who, message, fields) + "\n";
  } else {
    line = fmt::format("{}: {}\n", who, message);
  }
  std::fputs(line.c_str(), stderr);
}

}  // namespace sirad::logging
