// sirad: the live progress view of a cluster run. On a terminal, a frame redrawn in place: a
// global bar (bundles done of the budget, bundles/s, the error estimate, ETA, exchanges,
// traffic) and one row per node; otherwise a plain log line now and then. The text is built
// by pure functions of a Status (no clocks, plain ASCII), so tests can check it exactly.
#pragma once
#include <cstdio>
#include <string>
#include <vector>

#include "cluster/status.h"

namespace sirad::cluster {

// The lines of the view for a terminal `columns` wide (at least 40): the global bar, then one
// row per node "NAME  DEVICE  STATE  B bundles  R/s  idle Ts  Ts ago". No line is longer than
// `columns`: names and devices are cut (ending in '~'), and on narrow terminals the last fields
// are left off. Bytes outside printable ASCII become '?'; a dead node's row starts with "!" and
// shows the state "DEAD".
std::vector<std::string> live_lines(const Status& s, int columns);

// One log line: "sirad: 412/1000 bundles, 87.3 bundles/s, error 2.31%, 3 nodes (1 dead)".
std::string plain_line(const Status& s);

// The escape sequences that replace a frame of `previous_lines` lines (the cursor at the start
// of the line below it) with `lines`: up over the old frame, each line cleared and rewritten,
// any old lines left over cleared; the cursor ends below the new frame.
std::string redraw(int previous_lines, const std::vector<std::string>& lines);

// Writes the view to `out`: redrawn in place on a TTY (columns from $COLUMNS, else the
// terminal's size, else 100); otherwise plain_line at most every 10% of the budget or every
// 10 s of the run (by Status::elapsed_s), and always at finish. Quiet: nothing. Never throws.
class LiveView {
 public:
  LiveView(std::FILE* out, bool quiet);
  void update(const Status& s);
  void finish(const Status& s);  // the last frame (or line); later output goes below it

 private:
  void write(const std::string& text);
  std::FILE* out_;
  bool quiet_, tty_;
  int frame_lines_ = 0;                 // TTY: lines of the frame on screen
  uint64_t printed_done_ = 0;           // plain: bundles_done at the last line
  double printed_s_ = 0;                // plain: elapsed_s at the last line
};

// What a cluster driver (sirad render --nodes, sirad-coordinator) does with each Status: the
// live view on stderr and, if asked, --status-json rewritten at most once a second; finish()
// draws the last frame and writes the file with the last status. The file is best effort: a
// write that fails (a full disk, a directory in its place) is said once on stderr, and the run
// goes on; the previous file stays whole (written atomically).
class StatusReporter {
 public:
  StatusReporter(bool quiet, std::string json_path) : view_(stderr, quiet), json_(std::move(json_path)) {}
  void operator()(const Status& s);
  void finish();

 private:
  LiveView view_;
  void write_json(const Status& s);

  std::string json_;
  double json_at_ = -1;
  bool failing_ = false;  // the last write failed (said once until one succeeds)
  Status last_;
};

}  // namespace sirad::cluster
