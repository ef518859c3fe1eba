// util/yaml.h: the YAML walker's typed reads, key paths, line numbers,
// unknown and missing keys, and the writer's round trip.
#include "banmo/util/yaml.h"

#include <gtest/gtest.h>

#include <clocale>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace banmo {
namespace {

enum class Shade { kLight, kDark };

}  // namespace

template <>
struct EnumNames<Shade> {
  static constexpr std::pair<Shade, const char*> kNames[] = {{Shade::kLight, "light"},
                                                             {Shade::kDark, "dark"}};
};

namespace {

struct Inner {
  double weight = 1.0;
  Shade shade = Shade::kLight;
};

struct Outer {
  std::string name = "outer";
  int count = 3;
  uint32_t seed = 7;
  bool on = false;
  std::optional<double> scale;
  std::vector<double> fractions = {0.5};
  Inner inner;
  std::vector<Inner> items;
};

template <class V>
void VisitFields(V& v, Inner& o) {
  v("weight", o.weight);
  v("shade", o.shade);
}

template <class V>
void VisitFields(V& v, Outer& o) {
  v("name", o.name);
  v("count", o.count);
  v("seed", o.seed);
  v("on", o.on);
  v("scale", o.scale);
  v("fractions", o.fractions);
  v("inner", o.inner);
  v("items", o.items);
}

// The message of the InputError that reading `text` as an Outer throws.
std::string ReadError(const std::string& text) {
  try {
    Outer o;
    YamlNode::Parse(text, "t.yaml").ReadStruct(&o);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return "";
}

TEST(YamlNode, ReadsEveryTypeAndKeepsDefaultsOfAbsentKeys) {
  Outer o;
  YamlNode::Parse(
      "name: x\ncount: -4\nseed: 4294967295\non: true\nscale: 2.5\nfractions: [0.25, 1e-3]\n"
      "inner: {shade: dark}\nitems:\n  - {weight: 2}\n  - {}\n",
      "t.yaml")
      .ReadStruct(&o);
  EXPECT_EQ(o.name, "x");
  EXPECT_EQ(o.count, -4);
  EXPECT_EQ(o.seed, 4294967295u);
  EXPECT_TRUE(o.on);
  ASSERT_TRUE(o.scale.has_value());
  EXPECT_EQ(*o.scale, 2.5);
  EXPECT_EQ(o.fractions, (std::vector<double>{0.25, 1e-3}));
  EXPECT_EQ(o.inner.weight, 1.0);  // absent: the default
  EXPECT_EQ(o.inner.shade, Shade::kDark);
  ASSERT_EQ(o.items.size(), 2u);
  EXPECT_EQ(o.items[0].weight, 2.0);
  EXPECT_EQ(o.items[1].weight, 1.0);

  Outer auto_scale;
  auto_scale.scale = 3.0;
  YamlNode::Parse("scale: auto\nfractions:\n", "t.yaml").ReadStruct(&auto_scale);
  EXPECT_FALSE(auto_scale.scale.has_value());
  EXPECT_TRUE(auto_scale.fractions.empty());  // an empty value is the empty list
}

TEST(YamlNode, TypeErrorsNameFileKeyPathLineAndWhatWasExpected) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"count: 1.5\n", "t.yaml: key 'count' (line 1): expected an integer, got '1.5'"},
      {"count: 99999999999\n", "t.yaml: key 'count' (line 1): expected an integer, got"},
      {"seed: -1\n", "t.yaml: key 'seed' (line 1): expected an integer in 0..4294967295"},
      {"on: yes\n", "t.yaml: key 'on' (line 1): expected true or false, got 'yes'"},
      {"name: [a]\n", "t.yaml: key 'name' (line 1): expected a string, got a list"},
      {"inner: 5\n", "t.yaml: key 'inner' (line 1): expected a map, got '5'"},
      {"fractions: 4\n", "t.yaml: key 'fractions' (line 1): expected a list, got '4'"},
      {"\n\nfractions: [1, x]\n", "t.yaml: key 'fractions[1]' (line 3): expected a finite number"},
      {"items:\n  - {}\n  - weight: [1]\n",
       "t.yaml: key 'items[1].weight' (line 3): expected a finite number, got a list"},
      {"inner:\n  shade: dim\n",
       "t.yaml: inner.shade: expected one of {light, dark}, got 'dim' (line 2)"},
      {"scale: big\n", "t.yaml: key 'scale' (line 1): expected auto or a finite number > 0"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string message = ReadError(text);
    EXPECT_EQ(message.rfind(expected, 0), 0u) << text << "\n" << message;
  }
}

TEST(YamlNode, NonFiniteAndLocaleDependentNumbersAreRefused) {
  for (const char* value : {".nan", ".inf", "-.inf", "nan", "inf", "1e999", "1,5", "0x10"}) {
    const std::string message = ReadError(std::string("inner:\n  weight: ") + value + "\n");
    EXPECT_NE(message.find("key 'inner.weight' (line 2): expected a finite number"),
              std::string::npos)
        << value << ": " << message;
  }
  EXPECT_NE(ReadError("inner:\n  weight:\n").find("expected a finite number, got nothing"),
            std::string::npos);
  // The classic locale whatever the process's: "1.5" is 1.5.
  const char* previous = std::setlocale(LC_NUMERIC, nullptr);
  const std::string saved = previous ? previous : "C";
  std::setlocale(LC_NUMERIC, "de_DE.UTF-8");  // may not exist; then nothing changes
  Outer o;
  YamlNode::Parse("inner: {weight: 1.5}\n", "t.yaml").ReadStruct(&o);
  std::setlocale(LC_NUMERIC, saved.c_str());
  EXPECT_EQ(o.inner.weight, 1.5);
}

TEST(YamlNode, UnknownRepeatedAndMissingKeysNameThePathAndLine) {
  EXPECT_EQ(ReadError("count: 1\ncolour: red\n"), "t.yaml: unknown key 'colour' (line 2)");
  EXPECT_EQ(ReadError("items:\n  - {weight: 1}\n  - {wieght: 1}\n"),
            "t.yaml: unknown key 'items[1].wieght' (line 3)");
  EXPECT_EQ(ReadError("inner:\n  weight: 1\n  weight: 2\n"),
            "t.yaml: duplicate key 'inner.weight' (line 3)");
  EXPECT_EQ(ReadError("- 1\n"), "t.yaml: key '(top level)' (line 1): expected a map, got a list");

  const YamlNode root = YamlNode::Parse("\na:\n  b: 1\n", "t.yaml", "; try again");
  try {
    root["a"].Required("c");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "t.yaml: missing key 'a.c' (line 3); try again");
  }
  try {
    root.CheckKeys({"x", "y"}, YamlNode::ChoicesNote({"x", "y"}));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "t.yaml: unknown key 'a' (line 2) (expected one of: x, y); try again");
  }
  EXPECT_TRUE(root["a"].Has("b"));
  EXPECT_FALSE(root["a"].Has("c"));
  EXPECT_FALSE(root["a"]["b"].Has("c"));  // not a map
  EXPECT_EQ(root["a"].ValueOr("c", 4), 4);
  EXPECT_EQ(root["a"].ValueOr("b", 4), 1);
}

TEST(YamlNode, LinesAndPathsOfEveryKey) {
  const YamlNode root = YamlNode::Parse("a:\n  b: [1, 2]\n  c:\n    - x: 1\n", "t.yaml");
  EXPECT_EQ(root["a"]["c"][0]["x"].path(), "a.c[0].x");
  EXPECT_EQ(root["a"]["c"][0]["x"].line(), 4);
  EXPECT_EQ(root["a"]["missing"].line(), 0);
  EXPECT_EQ(root["a"]["missing"].LineNote(), "");
  const std::map<std::string, int> lines = root.KeyLines();
  EXPECT_EQ(lines.at("a"), 1);
  EXPECT_EQ(lines.at("a.b"), 2);
  EXPECT_EQ(lines.at("a.c[0]"), 4);
  EXPECT_EQ(lines.at("a.c[0].x"), 4);
}

TEST(YamlNode, SyntaxErrorsAndFilesNameTheSource) {
  try {
    YamlNode::Parse("a: [1,\n", "t.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("t.yaml: invalid YAML (line ", 0), 0u) << e.what();
  }
  try {
    YamlNode::Load("/nonexistent/x.yaml");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/x.yaml"), std::string::npos) << e.what();
  }
}

TEST(YamlNode, Vector3NeedsThreeFiniteNumbers) {
  const YamlNode root = YamlNode::Parse("a: [1, 2.5, -3]\nb: [1, 2]\nc: [1, .inf, 3]\n", "t.yaml");
  EXPECT_EQ(root["a"].As<Eigen::Vector3d>(), Eigen::Vector3d(1, 2.5, -3));
  EXPECT_THROW(root["b"].As<Eigen::Vector3d>(), InputError);
  try {
    root["c"].As<Eigen::Vector3d>();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("key 'c[1]' (line 3): expected a finite number"),
              std::string::npos)
        << e.what();
  }
}

struct OneLineInner {
  template <class S>
  static constexpr bool kOneLine = std::is_same_v<S, Inner>;
};

TEST(YamlWriter, WritesWhatTheReaderReadsBack) {
  Outer o;
  o.name = "";  // quoted, so that it does not read back as null
  o.count = -2;
  o.seed = 4294967295u;
  o.on = true;
  o.scale = 0.1;
  o.fractions = {0.1, 1.0 / 3.0, 1e-300};
  o.inner.weight = 2.0 / 3.0;
  o.inner.shade = Shade::kDark;
  o.items = {Inner{0.5, Shade::kLight}, Inner{}};
  for (bool one_line : {false, true}) {
    YAML::Emitter out;
    if (one_line) {
      YamlWriter<OneLineInner>(&out).Write(o);
    } else {
      YamlWriter<>(&out).Write(o);
    }
    ASSERT_TRUE(out.good()) << out.GetLastError();
    const std::string text = out.c_str();
    EXPECT_EQ(text.find("inner: {weight:") != std::string::npos, one_line) << text;
    EXPECT_NE(text.find("fractions: [0.1, "), std::string::npos) << text;
    Outer back;
    back.scale.reset();
    YamlNode::Parse(text, "written").ReadStruct(&back);
    EXPECT_EQ(back.name, o.name);
    EXPECT_EQ(back.count, o.count);
    EXPECT_EQ(back.seed, o.seed);
    EXPECT_EQ(back.on, o.on);
    EXPECT_EQ(back.scale, o.scale);
    EXPECT_EQ(back.fractions, o.fractions);  // exactly: the shortest form that reads back
    EXPECT_EQ(back.inner.weight, o.inner.weight);
    EXPECT_EQ(back.inner.shade, o.inner.shade);
    ASSERT_EQ(back.items.size(), 2u);
    EXPECT_EQ(back.items[0].weight, 0.5);
  }
  YAML::Emitter out;
  Outer empty_scale;
  YamlWriter<>(&out).Write(empty_scale);
  EXPECT_NE(std::string(out.c_str()).find("scale: auto"), std::string::npos) << out.c_str();
}

}  // namespace
}  // namespace banmo
