// Root-pose text files (io/dataset.cc, ReadPoseFile).
#include "banmo/io/dataset.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = banmo::fuzz::WriteInput("poses.txt", banmo::fuzz::AsString(data, size));
  banmo::fuzz::Expect([&] { banmo::ReadPoseFile(path); });
  return 0;
}
