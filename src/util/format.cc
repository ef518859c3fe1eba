#include "banmo/util/format.h"

#include <cstdio>
#include <cstdlib>

namespace banmo {

std::string FormatDouble(double v) {
  char buf[64];
  for (int precision = 15; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

}  // namespace banmo
