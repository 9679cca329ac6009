// sirad tests: one real message of every SIRAD/1 type (proto_test.cpp round-trips them; the
// fuzz corpus in tests/fuzz/corpus is made of them).
#pragma once
#include <cstring>
#include <initializer_list>
#include <string>
#include <vector>

#include "proto/codec.h"

namespace sirad::proto::test {

inline std::string doubles(std::initializer_list<double> v) {
  std::string s(v.size() * sizeof(double), '\0');
  std::memcpy(s.data(), std::data(v), s.size());
  return s;
}

inline std::vector<Message> one_of_each() {
  std::vector<Message> out;
  wire::Hello hello;
  hello.set_node_name("box-1");
  hello.set_sirad_version("0.1.0");
  hello.mutable_device()->set_name("pthread");
  hello.mutable_device()->set_compute_units(2);
  hello.add_scene_hashes("a228efa82102b19382e261846de1b214");
  out.push_back({Command::hello, hello, {}});
  wire::Welcome welcome;
  welcome.set_node_index(3);
  welcome.set_heartbeat_ms(1000);
  welcome.mutable_run()->set_seed(42);
  welcome.mutable_run()->add_chunk_starts(0);
  welcome.mutable_run()->add_chunk_starts(100);
  welcome.mutable_run()->set_topology("ring");
  out.push_back({Command::welcome, welcome, {}});
  wire::SceneChunk scene;
  scene.set_scene_hash("ab");
  scene.set_total_bytes(10);
  scene.set_offset(4);
  scene.set_last(true);
  out.push_back({Command::scene, scene, {std::string("sixbyt")}});
  wire::Ready ready;
  ready.set_ms_per_bundle(12.5);
  out.push_back({Command::ready, ready, {}});
  wire::Grant grant;
  grant.set_grant_id(7);
  auto* r = grant.add_ranges();
  r->set_first(100);
  r->set_last(164);
  grant.set_report_after(16);
  grant.add_report_chunks(1);
  out.push_back({Command::grant, grant, {}});
  wire::Report report;
  report.set_grant_id(7);
  report.add_chunks(1);
  report.add_counts(16);
  report.add_chunks(0);
  report.add_counts(16);
  out.push_back({Command::report, report, {doubles({1, 2, 3}), doubles({4, 5, 6, 7, 8, 9})}});
  out.push_back({Command::final_state, report, {doubles({1, 2, 3}), doubles({4, 5, 6})}});
  wire::Update update;
  update.set_exchange(2);
  update.add_chunks(5);
  update.add_counts(48);
  out.push_back({Command::update, update, {doubles({0.5, 0.25, 0.125})}});
  wire::Stop stop;
  stop.set_abandon_current(true);
  out.push_back({Command::stop, stop, {}});
  wire::Error error;
  error.set_reason("version mismatch");
  out.push_back({Command::error, error, {}});
  out.push_back({Command::heartbeat, std::monostate{}, {}});
  out.push_back({Command::bye, std::monostate{}, {}});
  wire::Image image;
  image.set_run_id(9);
  image.set_camera("eye 0 0 -1 look 0 0 0 up 0 1 0 fov 40");
  image.set_width(40);
  image.set_height(8);
  image.set_spp(4);
  image.set_seed(1);
  image.set_tile(32);
  out.push_back({Command::image, image, {doubles({1, 2, 3, 4, 5, 6})}});
  wire::Grant tiles;
  tiles.set_run_id(9);
  tiles.set_grant_id(2);
  auto* t = tiles.add_ranges();
  t->set_first(1);
  t->set_last(2);
  out.push_back({Command::tiles, tiles, {}});
  wire::Pixels pixels;
  pixels.set_run_id(9);
  pixels.set_grant_id(2);
  *pixels.add_done() = *t;
  pixels.set_busy_s(0.5);
  out.push_back({Command::pixels, pixels, {std::string(8 * 8 * kPixelBytes, '\0')}});
  return out;
}

}  // namespace sirad::proto::test
