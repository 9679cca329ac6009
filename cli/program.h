// sirad: what the three programs' mains share: the parse of their command line and the one
// line a failure prints. A program exits 0 when done, 1 on an error (one line, "PROGRAM: error:
// WHY"; out of memory said so), 2 on flags it cannot parse ("... (see PROGRAM --help)").
#pragma once
#include <functional>
#include <optional>

#include <CLI/CLI.hpp>

namespace sirad::cli {

// Parses `app`: nothing to go on with; else the exit status (--help and --version printed: 0; a
// flag that does not parse: 2, its line printed).
std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv, const char* program);

// `body`'s exit status, or 1 with its error's line when it throws.
int guarded(const char* program, const std::function<int()>& body);

}  // namespace sirad::cli
