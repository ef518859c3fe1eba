// Stage configs (optim/config.cc, ParseSolverConfig).
#include "banmo/optim/config.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = banmo::fuzz::AsString(data, size);
  banmo::fuzz::Expect([&] { banmo::ParseSolverConfig(text, "fuzz.yaml"); });
  return 0;
}
