// util/enum_names.h: one name table per enum for parsing, printing and errors.
#include "banmo/util/enum_names.h"

#include <gtest/gtest.h>

#include <string>

namespace banmo {
namespace {

enum class Fruit { kApple, kPear, kPlum, kUnlisted };
enum class NoTable { kA };

}  // namespace

template <>
struct EnumNames<Fruit> {
  static constexpr std::pair<Fruit, const char*> kNames[] = {
      {Fruit::kApple, "apple"}, {Fruit::kPear, "pear"}, {Fruit::kPlum, "plum"}};
};

namespace {

TEST(EnumNames, NameAndParseAreInverse) {
  for (Fruit f : {Fruit::kApple, Fruit::kPear, Fruit::kPlum}) {
    const std::optional<Fruit> parsed = ParseEnum<Fruit>(EnumName(f));
    ASSERT_TRUE(parsed.has_value()) << EnumName(f);
    EXPECT_EQ(*parsed, f);
  }
  EXPECT_STREQ(EnumName(Fruit::kPear), "pear");
}

TEST(EnumNames, UnknownNamesAndValues) {
  EXPECT_FALSE(ParseEnum<Fruit>("Apple").has_value());  // case matters
  EXPECT_FALSE(ParseEnum<Fruit>("").has_value());
  EXPECT_FALSE(ParseEnum<Fruit>("apple ").has_value());
  EXPECT_STREQ(EnumName(Fruit::kUnlisted), "?");
}

TEST(EnumNames, ChoicesListTheTableInOrder) {
  EXPECT_EQ(EnumChoices<Fruit>(), "{apple, pear, plum}");
}

TEST(EnumNames, HasEnumNamesDetectsTheTable) {
  static_assert(HasEnumNames<Fruit>::value);
  static_assert(!HasEnumNames<NoTable>::value);
  SUCCEED();
}

}  // namespace
}  // namespace banmo
