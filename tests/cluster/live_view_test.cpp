// sirad tests: the live view of a cluster run: the bar's numbers, the node rows (dead nodes,
// long names cut to the width), the plain log line, the ANSI redraw, and LiveView writing to
// a file, a pseudo-terminal, or nothing when quiet.
#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "cluster/live_view.h"

namespace sirad::cluster {
namespace {

Status three_nodes() {
  Status s;
  s.bundles_done = 412;
  s.bundles = 1000;
  s.elapsed_s = 4.72;  // 87.3 bundles/s, 588 left: ETA 7s
  s.error_estimate = 0.0231;
  s.exchanges = 12;
  s.bytes_in = 3'100'000;
  s.bytes_out = 3'140'000;
  s.nodes = {{"node-a", "NVIDIA H100 80GB HBM3", "working", 250, 7, 0.21, 53.0, 4.1, 0.4},
             {"gpu-box-2", "pthread-AMD EPYC 7B13", "waiting", 150, 5, 0.8, 31.8, 4.0, 1.2},
             {"laptop", "Intel(R) UHD Graphics 620", "dead", 12, 1, 31.0, 3.0, 3.9, 0.0}};
  return s;
}

// Everything written to `f` since it was opened.
std::string contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string text;
  for (int c; (c = std::fgetc(f)) != EOF;) text += static_cast<char>(c);
  return text;
}

TEST(LiveViewLines, BarShowsFractionAndNumbers) {
  auto lines = live_lines(three_nodes(), 200);
  ASSERT_EQ(lines.size(), 4u);  // the bar, then one row per node
  EXPECT_EQ(lines[0],
            "[############..................] 412/1000 bundles  87.3 bundles/s  error 2.31%  ETA 7s  "
            "12 exchanges  3.1 MB in / 3.1 MB out");
  EXPECT_EQ(lines[1], "  node-a     NVIDIA H100 80GB HBM3      working  250 bundles  53.0/s  idle 0.4s   0.2s ago");

  Status full = three_nodes();
  full.bundles_done = 1000;
  full.elapsed_s = 12.4;
  EXPECT_EQ(live_lines(full, 200)[0],
            "[##############################] 1000/1000 bundles  80.6 bundles/s  error 2.31%  done in 12s  "
            "12 exchanges  3.1 MB in / 3.1 MB out");
  // Narrow: fields are left off from the end, the bar is 40 - 3 - 16 = 21 wide, 41.2% of it filled.
  EXPECT_EQ(live_lines(three_nodes(), 40)[0], "[########.............] 412/1000 bundles");
  // With the run's patch count, patch-bundles per second follow bundles per second (87.3 x 20040).
  Status with_patches = three_nodes();
  with_patches.patches = 20040;
  EXPECT_EQ(live_lines(with_patches, 200)[0],
            "[############..................] 412/1000 bundles  87.3 bundles/s  1.75e+06 patch-bundles/s  error 2.31%  "
            "ETA 7s  12 exchanges  3.1 MB in / 3.1 MB out");
}

TEST(LiveViewLines, ErrorIsNaUntilThereIsAnEstimate) {
  Status s = three_nodes();
  s.error_estimate = -1;
  EXPECT_NE(live_lines(s, 200)[0].find("  error n/a  "), std::string::npos);
  EXPECT_EQ(plain_line(s), "sirad: 412/1000 bundles, 87.3 bundles/s, error n/a, 3 nodes (1 dead)");
  s.error_estimate = 0.00456;
  EXPECT_NE(live_lines(s, 200)[0].find("  error 0.46%  "), std::string::npos);
  EXPECT_EQ(plain_line(s), "sirad: 412/1000 bundles, 87.3 bundles/s, error 0.46%, 3 nodes (1 dead)");
}

// A quarantined node is flagged like a dead one in its row and counted apart in the plain line.
TEST(LiveViewLines, QuarantinedNodesAreFlagged) {
  Status s = three_nodes();
  s.nodes[1].state = "quarantined";
  s.nodes[1].why = "chunk 0 value 3 is nan";
  std::vector<std::string> lines = live_lines(s, 200);
  EXPECT_EQ(lines[2].rfind("! gpu-box-2", 0), 0u) << lines[2];
  EXPECT_NE(lines[2].find("QUARANTINED"), std::string::npos) << lines[2];
  EXPECT_EQ(plain_line(s), "sirad: 412/1000 bundles, 87.3 bundles/s, error 2.31%, 3 nodes (1 dead, 1 quarantined)");
  EXPECT_NE(to_json(s).find("\"why\":\"chunk 0 value 3 is nan\""), std::string::npos);
}

TEST(LiveViewLines, EtaFromTheRunRate) {
  Status s = three_nodes();
  auto bar = [&] { return live_lines(s, 200)[0]; };
  s.bundles_done = 500, s.elapsed_s = 10;  // 50/s, 500 left
  EXPECT_NE(bar().find("  ETA 10s  "), std::string::npos) << bar();
  s.bundles = 100'000, s.bundles_done = 100;  // 10/s, 99900 s left
  EXPECT_NE(bar().find("  ETA 2h46m  "), std::string::npos) << bar();
  s.bundles_done = 0;
  EXPECT_NE(bar().find("  ETA n/a  "), std::string::npos) << bar();
  s.bundles_done = s.bundles, s.elapsed_s = 125;
  EXPECT_NE(bar().find("  done in 2m05s  "), std::string::npos) << bar();
}

TEST(LiveViewLines, DeadNodeIsMarked) {
  auto lines = live_lines(three_nodes(), 100);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[3].substr(0, 9), "! laptop ");
  EXPECT_NE(lines[3].find("  DEAD  "), std::string::npos);
  EXPECT_NE(lines[3].find("31.0s ago"), std::string::npos);
  for (int i : {1, 2}) {
    EXPECT_EQ(lines[i].substr(0, 2), "  ");
    EXPECT_EQ(lines[i].find("DEAD"), std::string::npos);
  }
}

TEST(LiveViewLines, NoLineLongerThanTheColumns) {
  Status s = three_nodes();
  s.nodes[0].name = std::string(300, 'n');
  s.nodes[1].device = std::string(300, 'd') + "\x1b[2J\xc3\xa9";  // and no escapes or UTF-8 get through
  for (int columns : {10, 40, 41, 60, 80, 100, 133, 200}) {
    auto lines = live_lines(s, columns);
    ASSERT_EQ(lines.size(), 4u);
    for (const auto& line : lines) {
      EXPECT_LE(static_cast<int>(line.size()), std::max(columns, 40)) << columns << ": " << line;
      for (char c : line) EXPECT_TRUE(c >= 0x20 && c <= 0x7e) << columns << ": " << line;
    }
    EXPECT_EQ(lines[1].substr(0, 9), "  nnnnnnn") << columns;  // the name is cut, not dropped
    EXPECT_NE(lines[1].find("~ "), std::string::npos) << columns;
    EXPECT_NE(lines[1].find("working"), std::string::npos) << columns;
  }
}

TEST(LiveViewLines, PlainLine) {
  Status s = three_nodes();
  EXPECT_EQ(plain_line(s), "sirad: 412/1000 bundles, 87.3 bundles/s, error 2.31%, 3 nodes (1 dead)");
  s.nodes.resize(1);
  EXPECT_EQ(plain_line(s), "sirad: 412/1000 bundles, 87.3 bundles/s, error 2.31%, 1 node");
}

TEST(LiveViewRedraw, MovesUpOverThePreviousFrame) {
  EXPECT_EQ(redraw(0, {"a", "b"}), "\x1b[2Ka\n\x1b[2Kb\n");
  // A node joined: up over 2 lines, 3 written.
  EXPECT_EQ(redraw(2, {"a", "b", "c"}), "\x1b[2A\x1b[2Ka\n\x1b[2Kb\n\x1b[2Kc\n");
  // Fewer lines: the old ones left over are cleared and the cursor goes back below the new frame.
  EXPECT_EQ(redraw(3, {"a"}), "\x1b[3A\x1b[2Ka\n\x1b[2K\n\x1b[2K\n\x1b[2A");
}

TEST(LiveViewWriter, PlainLinesEveryTenthOrTenSecondsOnAFile) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  LiveView view(f, false);
  Status s;
  s.bundles = 1000;
  auto at = [&](uint64_t done, double seconds) {
    s.bundles_done = done, s.elapsed_s = seconds;
    view.update(s);
  };
  at(50, 1);    // nothing: under 10% and 10 s
  at(100, 2);   // 10%
  at(150, 3);   // nothing
  at(250, 4);   // 20%
  at(260, 14);  // 10 s since the last line
  at(270, 15);  // nothing
  s.bundles_done = 1000, s.elapsed_s = 16;
  view.finish(s);
  EXPECT_EQ(contents(f),
            "sirad: 100/1000 bundles, 50.0 bundles/s, error n/a, 0 nodes\n"
            "sirad: 250/1000 bundles, 62.5 bundles/s, error n/a, 0 nodes\n"
            "sirad: 260/1000 bundles, 18.6 bundles/s, error n/a, 0 nodes\n"
            "sirad: 1000/1000 bundles, 62.5 bundles/s, error n/a, 0 nodes\n");
  std::fclose(f);
}

TEST(LiveViewWriter, QuietWritesNothing) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  LiveView view(f, true);
  Status s = three_nodes();
  view.update(s);
  s.bundles_done = s.bundles;
  view.finish(s);
  EXPECT_EQ(contents(f), "");
  std::fclose(f);
}

// On a pseudo-terminal: each frame is redrawn over the last, also when a node joins.
TEST(LiveViewWriter, RedrawsInPlaceOnATerminal) {
  int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (master < 0) GTEST_SKIP() << "no pseudo-terminals here";
  ASSERT_EQ(::grantpt(master), 0);
  ASSERT_EQ(::unlockpt(master), 0);
  std::FILE* tty = std::fopen(::ptsname(master), "w");
  ASSERT_NE(tty, nullptr);
  termios raw{};
  ASSERT_EQ(::tcgetattr(::fileno(tty), &raw), 0);
  raw.c_oflag &= ~OPOST;  // "\n" as written, not "\r\n"
  ASSERT_EQ(::tcsetattr(::fileno(tty), TCSANOW, &raw), 0);
  const char* old_columns = std::getenv("COLUMNS");
  std::string saved = old_columns ? old_columns : "";
  ::setenv("COLUMNS", "72", 1);

  Status two = three_nodes();
  two.nodes.resize(2);
  Status three = three_nodes();
  LiveView view(tty, false);
  view.update(two);
  view.update(three);
  view.finish(three);
  std::fclose(tty);
  if (old_columns) ::setenv("COLUMNS", saved.c_str(), 1);
  else ::unsetenv("COLUMNS");

  std::string got;
  char buf[4096];
  for (pollfd p{master, POLLIN, 0}; ::poll(&p, 1, 200) > 0;) {
    ssize_t n = ::read(master, buf, sizeof buf);
    if (n <= 0) break;
    got.append(buf, static_cast<size_t>(n));
  }
  ::close(master);
  EXPECT_EQ(got, redraw(0, live_lines(two, 72)) + redraw(3, live_lines(three, 72)) +
                     redraw(4, live_lines(three, 72)));
}

}  // namespace
}  // namespace sirad::cluster
