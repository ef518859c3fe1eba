#include "banmo/util/error.h"

#include <gtest/gtest.h>

#include <string>

namespace banmo {
namespace {

TEST(ThrowInputError, StreamsEveryArgumentIntoTheMessage) {
  try {
    ThrowInputError("data/manifest.yaml", ": expected ", 16, " channels, got ", 2.5);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "data/manifest.yaml: expected 16 channels, got 2.5");
  }
}

TEST(ThrowInputError, IsARuntimeError) { EXPECT_THROW(ThrowInputError("x"), std::runtime_error); }

}  // namespace
}  // namespace banmo
