// sirad fuzzing: libFuzzer entry point for the checkpoint decoder (cluster/checkpoint.h). An
// input is a checkpoint's payload (a serialised wire::Checkpoint, or anything); the target
// frames it with a valid header and checksum, so the fuzzer explores the field checks behind
// the checksum. decode_checkpoint must refuse it with a sirad::Error or return a checkpoint
// that resumes a policy (snapshot_of, settings_of) without any other exception. Built with
// `CC=clang CXX=clang++ cmake -DSIRAD_FUZZ=ON`; .ci/run runs it for 60 s from
// tests/fuzz/checkpoint_corpus (the golden run's checkpoint, less its header).
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "cluster/checkpoint.h"
#include "util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes = sirad::cluster::frame_checkpoint(std::string_view(reinterpret_cast<const char*>(data), size));
  try {
    const sirad::wire::Checkpoint c = sirad::cluster::decode_checkpoint(bytes, "fuzz");
    sirad::cluster::settings_of(c);
    sirad::cluster::snapshot_of(c);
  } catch (const sirad::Error&) {
    return 0;  // refused
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad fuzz: %s\n", e.what());
    std::abort();
  }
  return 0;
}
