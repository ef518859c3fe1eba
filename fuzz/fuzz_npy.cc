// .npy arrays: features, depth, flow (io/npy.cc).
#include "banmo/io/npy.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes = banmo::fuzz::AsString(data, size);
  banmo::fuzz::Expect([&] { banmo::DecodeNpy(bytes, "fuzz.npy"); });
  return 0;
}
