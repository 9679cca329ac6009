// sirad fuzzing: libFuzzer entry point for the SIRAD/1 decoder (see decode_fuzz.h). Built with
// `CC=clang CXX=clang++ cmake -DSIRAD_FUZZ=ON`; .ci/run runs it for 60 s from tests/fuzz/corpus.
#include <cstdio>
#include <cstdlib>

#include "decode_fuzz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    sirad::proto::fuzz::decode_one(data, size);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad fuzz: %s\n", e.what());
    std::abort();
  }
  return 0;
}
