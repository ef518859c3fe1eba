// Checksums of binary files (params.bin, state.bin), recorded in the YAML
// beside them so that a flipped bit or a partial copy is an error naming the
// file instead of a silent change.
#pragma once

#include <string>

namespace banmo {

// "fnv1a64:" followed by the 16 hex digits of the 64-bit FNV-1a hash of
// `bytes` (not cryptographic: it detects damage, not tampering).
std::string ContentChecksum(const std::string& bytes);

// Throws InputError naming `path` unless ContentChecksum(bytes) equals
// `recorded` (the value found under `key` in `yaml_path`).
void VerifyChecksum(const std::string& path, const std::string& bytes, const std::string& recorded,
                    const std::string& yaml_path, const std::string& key);

}  // namespace banmo
