#include "banmo/geometry/box.h"

#include <gtest/gtest.h>

#include <limits>

namespace banmo {
namespace {

TEST(IsValidBox, FiniteWithPositiveExtentOnEveryAxis) {
  const Eigen::Vector3d lo(-1, -0.5, 0), hi(1, 0.5, 2);
  EXPECT_TRUE(IsValidBox(Eigen::AlignedBox3d(lo, hi)));
  EXPECT_FALSE(IsValidBox(Eigen::AlignedBox3d()));  // empty (Eigen's default)
  EXPECT_FALSE(IsValidBox(Eigen::AlignedBox3d(lo, Eigen::Vector3d(1, -0.5, 2))));  // flat in y
  EXPECT_FALSE(IsValidBox(Eigen::AlignedBox3d(hi, lo)));                           // max < min
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(IsValidBox(Eigen::AlignedBox3d(lo, Eigen::Vector3d(1, inf, 2))));
  EXPECT_FALSE(IsValidBox(Eigen::AlignedBox3d(Eigen::Vector3d(nan, 0, 0), hi)));
}

}  // namespace
}  // namespace banmo
