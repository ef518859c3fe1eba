// Shared third-party assets (the Fox glTF) that tests read from the shared/
// folder beside the checkout (BANMO_SHARED_DIR, tests/CMakeLists.txt). A
// missing asset is a failure with one message, never a skip: CI runs on a
// clone beside shared/, so a skip would hide that the Fox went untested.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace banmo::testing {

// The path of `relative` (e.g. "data/gltf/Fox/Fox.glb") under shared/.
inline std::string SharedAsset(const std::string& relative) {
  return std::string(BANMO_SHARED_DIR) + "/" + relative;
}

// Use as ASSERT_TRUE(SharedAssetExists(path)) at the top of a test.
inline ::testing::AssertionResult SharedAssetExists(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << path
         << " not found: tests read shared assets from BANMO_SHARED_DIR, the shared/ folder "
            "beside the checkout (configure with -DBANMO_SHARED_DIR=<dir> to use another)";
}

}  // namespace banmo::testing
