// model/parameter_group.h: the group names and ParameterGroupSet.
#include "banmo/model/parameter_group.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace banmo {
namespace {

TEST(ParameterGroup, EveryGroupHasOneUniqueName) {
  const auto& names = EnumNames<ParameterGroup>::kNames;
  ASSERT_EQ(static_cast<int>(std::size(names)), kNumParameterGroups);
  std::set<std::string> seen;
  for (int g = 0; g < kNumParameterGroups; ++g) {
    const auto group = static_cast<ParameterGroup>(g);
    const std::string name = EnumName(group);
    EXPECT_NE(name, "?") << g;
    EXPECT_TRUE(seen.insert(name).second) << name;
    EXPECT_EQ(ParseEnum<ParameterGroup>(name), group) << name;
  }
  // The config spellings (docs/config.md, `constant:`).
  EXPECT_EQ(ParseEnum<ParameterGroup>("bones_t"), ParameterGroup::kBonesT);
  EXPECT_EQ(ParseEnum<ParameterGroup>("log_beta"), ParameterGroup::kLogBeta);
}

TEST(ParameterGroupSet, InsertEraseContains) {
  ParameterGroupSet set;
  EXPECT_TRUE(set.empty());
  set.Insert(ParameterGroup::kRoot);
  set.Insert(ParameterGroup::kPoseCode);  // the last group
  EXPECT_FALSE(set.empty());
  for (int g = 0; g < kNumParameterGroups; ++g) {
    const auto group = static_cast<ParameterGroup>(g);
    EXPECT_EQ(set.Contains(group),
              group == ParameterGroup::kRoot || group == ParameterGroup::kPoseCode)
        << EnumName(group);
  }
  set.Insert(ParameterGroup::kRoot);  // twice: still one member
  set.Erase(ParameterGroup::kRoot);
  EXPECT_FALSE(set.Contains(ParameterGroup::kRoot));
  set.Erase(ParameterGroup::kSdf);  // not a member: no change
  EXPECT_TRUE(set.Contains(ParameterGroup::kPoseCode));
  set.Erase(ParameterGroup::kPoseCode);
  EXPECT_TRUE(set.empty());
}

TEST(ParameterGroupSet, EqualityAndInitializerList) {
  const ParameterGroupSet a{ParameterGroup::kSdf, ParameterGroup::kColor};
  ParameterGroupSet b;
  b.Insert(ParameterGroup::kColor);
  EXPECT_FALSE(a == b);
  b.Insert(ParameterGroup::kSdf);
  EXPECT_TRUE(a == b);
  EXPECT_TRUE(ParameterGroupSet{} == ParameterGroupSet());
}

}  // namespace
}  // namespace banmo
