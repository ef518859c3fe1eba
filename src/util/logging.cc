#include "banmo/util/logging.h"

#include <mutex>

namespace banmo {

void InitLogging(const char* argv0) {
  static std::once_flag once;
  std::call_once(once, [argv0]() {
    FLAGS_logtostderr = true;
    google::InitGoogleLogging(argv0);
  });
}

}  // namespace banmo
