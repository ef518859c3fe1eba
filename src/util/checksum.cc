#include "banmo/util/checksum.h"

#include <cstdint>
#include <cstdio>

#include "banmo/util/error.h"

namespace banmo {

std::string ContentChecksum(const std::string& bytes) {
  std::uint64_t hash = 14695981039346656037ull;  // FNV-1a offset basis
  for (const char c : bytes) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 1099511628211ull;  // FNV prime
  }
  char hex[32];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(hash));
  return std::string("fnv1a64:") + hex;
}

void VerifyChecksum(const std::string& path, const std::string& bytes, const std::string& recorded,
                    const std::string& yaml_path, const std::string& key) {
  const std::string actual = ContentChecksum(bytes);
  if (actual != recorded) {
    ThrowInputError(path, ": checksum ", actual, " does not match ", recorded, " recorded in ",
                    yaml_path, " (key '", key,
                    "'): the file is damaged (a changed byte or a partial copy)");
  }
}

}  // namespace banmo
