// sirad: --log-format and --log-level, the same on sirad-node and sirad-coordinator (util/log.h).
#pragma once
#include <string>

#include <CLI/CLI.hpp>

#include "util/log.h"

namespace sirad::cli {

struct LogFlags {
  std::string format = "text", level = "info";
  void add(CLI::App& app) {
    app.add_option("--log-format", format, "Log lines as text or json (one object per line, for log collectors)")
        ->check(CLI::IsMember({"text", "json"}))
        ->capture_default_str();
    app.add_option("--log-level", level, "Least severe lines logged: error, warn, info or debug (debug: every grant)")
        ->check(CLI::IsMember({"error", "warn", "info", "debug"}))
        ->capture_default_str();
  }
  void apply() const { logging::configure(logging::parse_level(level, "--log-level"), logging::parse_format(format, "--log-format")); }
};

}  // namespace sirad::cli
