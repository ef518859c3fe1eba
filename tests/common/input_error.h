// Test helper: the message of the InputError a callable throws.
#pragma once

#include <functional>
#include <string>

#include "banmo/util/error.h"

namespace banmo {
namespace testing {

// The message of the InputError thrown by fn ("" if none is thrown).
inline std::string ErrorOf(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace testing
}  // namespace banmo
