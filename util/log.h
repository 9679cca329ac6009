// sirad: the operator's log of the programs that run for long (sirad-node, sirad-coordinator):
// one line per event on stderr, as text ("WHO: message") or, for log collectors, JSON (one
// object per line: time, level, who, message, and the event's fields), below a level dropped.
// Process-wide; thread-safe. Without configure(): text at info, as the embedded cluster prints.
#pragma once
#include <string>

#include <nlohmann/json.hpp>

namespace sirad::logging {

enum class Level { error, warn, info, debug };
enum class Format { text, json };

// Throws sirad::Error naming `flag` for a name that is not a level / format.
Level parse_level(const std::string& name, const std::string& flag);
Format parse_format(const std::string& name, const std::string& flag);

void configure(Level level, Format format);
bool enabled(Level level);

// `who`: the program and, for a node, its name ("sirad-node box-3"); `fields`: a JSON object of
// the event's values (in JSON lines only; the text line says them in `message`).
void write(Level level, const std::string& who, const std::string& message, const nlohmann::json& fields = nlohmann::json::object());

// The JSON line of an event at `unix_seconds` (write() uses the clock; tests pass a time).
std::string json_line(double unix_seconds, Level level, const std::string& who, const std::string& message,
                      const nlohmann::json& fields);

}  // namespace sirad::logging
