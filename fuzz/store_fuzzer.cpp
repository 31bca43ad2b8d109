// libFuzzer target for MeshStore::open: the input is a whole store laid end to end (layout in
// fuzz_common.h, write_store_input); an opened store must be safe to walk.
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  streamcvd::fuzz::run_store_input(data, size);
  return 0;
}
