// libFuzzer target for one mesh reader, built once per format (STREAMCVD_FUZZ_EXTENSION is
// ".ply", ".obj", ".off" or ".stl"). The input's first byte picks zstd compression and whether
// the file has an extension (see fuzz_common.h); the rest is the file.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_common.h"

#ifndef STREAMCVD_FUZZ_EXTENSION
#error "define STREAMCVD_FUZZ_EXTENSION"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  streamcvd::fuzz::run_mesh_input(data, size, STREAMCVD_FUZZ_EXTENSION);
  return 0;
}
