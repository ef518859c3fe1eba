#include "banmo/geometry/camera.h"

#include <cmath>

namespace banmo {

bool PinholeCamera::IsValid() const {
  return width > 0 && height > 0 && intrinsics.allFinite() && intrinsics[0] > 0 &&
         intrinsics[1] > 0;
}

}  // namespace banmo
