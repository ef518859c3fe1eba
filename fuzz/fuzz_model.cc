// Model folders (model/model_file.cc): the input is a 4-byte little-endian
// length L, then L bytes of model.yaml, then params.bin.
#include <cstring>
#include <filesystem>

#include "banmo/model/model_file.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 4) return 0;
  uint32_t length = 0;
  std::memcpy(&length, data, 4);
  if (length > size - 4) return 0;
  const std::string dir = banmo::fuzz::WorkDir() + "/model";
  std::filesystem::create_directories(dir);
  banmo::fuzz::WriteInput("model/model.yaml", banmo::fuzz::AsString(data + 4, length));
  banmo::fuzz::WriteInput("model/params.bin",
                          banmo::fuzz::AsString(data + 4 + length, size - 4 - length));
  banmo::fuzz::Expect([&] { banmo::ReadModelFiles(dir); });
  return 0;
}
