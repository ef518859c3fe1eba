#include "banmo/util/format.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <vector>

namespace banmo {
namespace {

// Exact: FormatDouble promises a string that reads back to the same bits.
TEST(FormatDouble, RoundTripsExactly) {
  std::vector<double> values = {0.0,
                                -0.0,
                                1.0,
                                0.1,
                                -2.5,
                                1e-300,
                                1e300,
                                M_PI,
                                1.0 / 3.0,
                                123456789.125,
                                std::numeric_limits<double>::denorm_min(),
                                std::numeric_limits<double>::max()};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < 1000; ++i) values.push_back(unit(rng) * std::pow(10.0, i % 40 - 20));
  for (double v : values) {
    const std::string text = FormatDouble(v);
    EXPECT_EQ(std::strtod(text.c_str(), nullptr), v) << text;
  }
}

TEST(FormatDouble, IsShortForShortNumbers) {
  EXPECT_EQ(FormatDouble(1.0), "1");
  EXPECT_EQ(FormatDouble(0.5), "0.5");
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(128.0), "128");
}

}  // namespace
}  // namespace banmo
