// manifest.yaml of a dataset (io/manifest.cc).
#include "fuzz_util.h"
#include "manifest.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path =
      banmo::fuzz::WriteInput("manifest.yaml", banmo::fuzz::AsString(data, size));
  banmo::fuzz::Expect([&] { banmo::internal::ReadManifest(path); });
  return 0;
}
