// sirad: the live progress view of a cluster run (the frame text, its ANSI redraw, the writer).
#include "cluster/live_view.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include <fmt/format.h>

namespace sirad::cluster {

namespace {

constexpr int min_columns = 40;

// Names and devices come from the network: only printable ASCII reaches the terminal.
std::string ascii(const std::string& s) { return peer_text(s, s.size()); }

// `s` padded or cut to exactly `width` characters; a cut one ends in '~'.
std::string fit(const std::string& s, size_t width) {
  if (s.size() <= width) return s + std::string(width - s.size(), ' ');
  if (width == 0) return {};
  return s.substr(0, width - 1) + '~';
}

// Seconds as "0.4s", "42.0s", "3m05s" or "2h07m".
std::string duration(double s, bool tenths) {
  s = std::max(s, 0.0);
  if (s < 60) return tenths ? fmt::format("{:.1f}s", s) : fmt::format("{:.0f}s", s);
  auto whole = static_cast<uint64_t>(s);
  if (whole < 3600) return fmt::format("{}m{:02}s", whole / 60, whole % 60);
  return fmt::format("{}h{:02}m", whole / 3600, whole % 3600 / 60);
}

std::string bytes(uint64_t n) {
  if (n < 1000) return fmt::format("{} B", n);
  const char* units[] = {"kB", "MB", "GB", "TB"};
  double v = static_cast<double>(n) / 1000;
  int u = 0;
  for (; v >= 999.95 && u < 3; ++u) v /= 1000;
  return fmt::format("{:.1f} {}", v, units[u]);
}

double run_rate(const Status& s) {
  return s.elapsed_s > 0 ? static_cast<double>(s.bundles_done) / s.elapsed_s : 0.0;
}

std::string error_text(const Status& s) {
  return s.error_estimate < 0 ? "error n/a" : fmt::format("error {:.2f}%", 100 * s.error_estimate);
}

// "[#####.....] 412/1000 bundles  87.3 bundles/s  error 2.31%  ETA 7s  12 exchanges  ...": the
// bar is 10 to 30 wide; fields are left off from the end while it would not fit.
std::string bar_line(const Status& s, int columns) {
  double rate = run_rate(s);
  bool finished = s.bundles > 0 && s.bundles_done >= s.bundles;
  double left = s.bundles > s.bundles_done ? static_cast<double>(s.bundles - s.bundles_done) : 0.0;
  std::string eta = finished  ? fmt::format("done in {}", duration(s.elapsed_s, false))
                    : rate > 0 ? fmt::format("ETA {}", duration(left / rate, false))
                               : std::string("ETA n/a");
  std::vector<std::string> fields = {
      fmt::format("{}/{} bundles", s.bundles_done, s.bundles),
      fmt::format("{:.1f} bundles/s", rate),
      error_text(s),
      eta,
      fmt::format("{} exchanges", s.exchanges),
      fmt::format("{} in / {} out", bytes(s.bytes_in), bytes(s.bytes_out)),
  };
  if (s.patches > 0) fields.insert(fields.begin() + 2, fmt::format("{:.3g} patch-bundles/s", rate * static_cast<double>(s.patches)));
  std::string text;
  for (;;) {
    text.clear();
    for (const auto& f : fields) {
      if (!text.empty()) text += "  ";
      text += f;
    }
    if (fields.size() == 1 || static_cast<int>(text.size()) + 3 + 10 <= columns) break;
    fields.pop_back();
  }
  int width = std::clamp(columns - 3 - static_cast<int>(text.size()), 10, 30);
  double fraction = s.bundles > 0 ? std::min(1.0, static_cast<double>(s.bundles_done) / s.bundles) : 0.0;
  auto filled = static_cast<size_t>(fraction * width);
  std::string line = fmt::format("[{}{}] {}", std::string(filled, '#'), std::string(width - filled, '.'), text);
  if (static_cast<int>(line.size()) > columns) line.resize(columns);  // huge numbers only
  return line;
}

}  // namespace

std::vector<std::string> live_lines(const Status& s, int columns) {
  columns = std::max(columns, min_columns);
  std::vector<std::string> lines = {bar_line(s, columns)};

  // The cells of each node's row, then one width per column so the rows line up: name,
  // device, then the state (left-aligned) and the numbers (right-aligned).
  struct Row {
    std::string name, device;
    std::vector<std::string> tail;
  };
  std::vector<Row> rows;
  size_t name_w = 0, device_w = 0;
  std::vector<size_t> tail_w(5, 0);
  for (const auto& n : s.nodes) {
    Row r{ascii(n.name), ascii(n.device),
          {n.state == "dead" ? "DEAD" : n.state == "quarantined" ? "QUARANTINED" : ascii(n.state),
           fmt::format("{} bundles", n.bundles),
           fmt::format("{:.1f}/s", n.rate), fmt::format("idle {}", duration(n.idle_s, true)),
           fmt::format("{} ago", duration(n.last_seen_s, true))}};
    name_w = std::max(name_w, r.name.size());
    device_w = std::max(device_w, r.device.size());
    for (size_t j = 0; j < tail_w.size(); ++j) tail_w[j] = std::max(tail_w[j], r.tail[j].size());
    rows.push_back(std::move(r));
  }

  // The name keeps at least 8 (or all of it); tail columns are left off from the end while even
  // that does not fit. A cut name keeps 2/3 of the room, the device what is left (none below 4).
  auto tail_size = [&] {
    int size = 0;
    for (size_t w : tail_w) size += 2 + static_cast<int>(w);
    return size;
  };
  while (tail_w.size() > 1 && 2 + static_cast<int>(std::min<size_t>(name_w, 8)) + tail_size() > columns)
    tail_w.pop_back();
  int avail = columns - 2 - tail_size() - (device_w > 0 ? 2 : 0);
  if (static_cast<int>(name_w + device_w) > avail) {
    int keep_name = std::max({avail - static_cast<int>(device_w), avail * 2 / 3, 8});
    name_w = std::min(name_w, static_cast<size_t>(keep_name));
    int device_left = avail - static_cast<int>(name_w);
    device_w = device_left >= 4 ? std::min(device_w, static_cast<size_t>(device_left)) : 0;
  }

  for (const auto& r : rows) {
    bool dead = r.tail[0] == "DEAD" || r.tail[0] == "QUARANTINED";
    std::string line = fmt::format("{} {}", dead ? '!' : ' ', fit(r.name, name_w));
    if (device_w > 0) line += fmt::format("  {}", fit(r.device, device_w));
    for (size_t j = 0; j < tail_w.size(); ++j)
      line += j == 0 ? fmt::format("  {:<{}}", r.tail[j], tail_w[j]) : fmt::format("  {:>{}}", r.tail[j], tail_w[j]);
    if (static_cast<int>(line.size()) > columns) line.resize(columns);  // huge numbers only
    lines.push_back(std::move(line));
  }
  return lines;
}

std::string plain_line(const Status& s) {
  size_t dead = std::count_if(s.nodes.begin(), s.nodes.end(), [](const auto& n) { return n.state == "dead"; });
  size_t quarantined = std::count_if(s.nodes.begin(), s.nodes.end(), [](const auto& n) { return n.state == "quarantined"; });
  std::string out;
  if (dead > 0) out = fmt::format("{} dead", dead);
  if (quarantined > 0) out += fmt::format("{}{} quarantined", out.empty() ? "" : ", ", quarantined);
  return fmt::format("sirad: {}/{} bundles, {:.1f} bundles/s, {}, {} node{}{}", s.bundles_done, s.bundles,
                     run_rate(s), error_text(s), s.nodes.size(), s.nodes.size() == 1 ? "" : "s",
                     out.empty() ? std::string() : " (" + out + ")");
}

std::string redraw(int previous_lines, const std::vector<std::string>& lines) {
  std::string out;
  if (previous_lines > 0) out += fmt::format("\x1b[{}A", previous_lines);
  for (const auto& line : lines) out += fmt::format("\x1b[2K{}\n", line);
  int left_over = previous_lines - static_cast<int>(lines.size());
  if (left_over > 0) {
    for (int i = 0; i < left_over; ++i) out += "\x1b[2K\n";
    out += fmt::format("\x1b[{}A", left_over);
  }
  return out;
}

namespace {

int terminal_columns(std::FILE* out) {
  if (const char* env = std::getenv("COLUMNS")) {
    int c = std::atoi(env);
    if (c > 0) return c;
  }
  winsize ws{};
  if (::ioctl(::fileno(out), TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) return ws.ws_col;
  return 100;
}

}  // namespace

LiveView::LiveView(std::FILE* out, bool quiet)
    : out_(out), quiet_(quiet || out == nullptr), tty_(!quiet_ && ::isatty(::fileno(out))) {}

void LiveView::write(const std::string& text) {
  std::fputs(text.c_str(), out_);
  std::fflush(out_);
}

void LiveView::update(const Status& s) {
  if (quiet_) return;
  try {
    if (tty_) {
      auto lines = live_lines(s, terminal_columns(out_));
      write(redraw(frame_lines_, lines));
      frame_lines_ = static_cast<int>(lines.size());
      return;
    }
    uint64_t total = std::max<uint64_t>(s.bundles, 1);
    if (s.bundles_done * 10 / total > printed_done_ * 10 / total || s.elapsed_s - printed_s_ >= 10) {
      write(plain_line(s) + '\n');
      printed_done_ = s.bundles_done;
      printed_s_ = s.elapsed_s;
    }
  } catch (...) {
    // A progress view is not worth failing a run over.
  }
}

void LiveView::finish(const Status& s) {
  if (quiet_) return;
  try {
    if (tty_) {
      update(s);
      frame_lines_ = 0;  // the frame stays; what comes next goes below it
    } else {
      write(plain_line(s) + '\n');
      printed_done_ = s.bundles_done;
      printed_s_ = s.elapsed_s;
    }
  } catch (...) {
  }
}

void StatusReporter::operator()(const Status& s) {
  last_ = s;
  view_.update(s);
  if (!json_.empty() && (json_at_ < 0 || s.elapsed_s - json_at_ >= 1.0)) {
    write_json(s);
    json_at_ = s.elapsed_s;
  }
}

void StatusReporter::finish() {
  view_.finish(last_);
  if (!json_.empty()) write_json(last_);
}

void StatusReporter::write_json(const Status& s) {
  try {
    write_status(json_, s);
    if (failing_) std::fprintf(stderr, "sirad: --status-json %s written again\n", json_.c_str());
    failing_ = false;
  } catch (const std::exception& e) {
    if (!failing_) std::fprintf(stderr, "sirad: --status-json not written (%s); the run goes on\n", e.what());
    failing_ = true;
  }
}

}  // namespace sirad::cluster
