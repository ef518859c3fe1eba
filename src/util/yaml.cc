#include "banmo/util/yaml.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <locale>
#include <sstream>

#include "banmo/util/input_file.h"

namespace banmo {
namespace {

std::string Join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

// A scalar holding a finite number (classic locale); false on anything else.
bool ParseFiniteNumber(const YAML::Node& node, double* value) {
  if (!node.IsDefined() || !node.IsScalar()) return false;
  std::istringstream in(node.Scalar());
  in.imbue(std::locale::classic());
  double v = 0.0;
  in >> v;
  if (in.fail() || !(in >> std::ws).eof() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

int LineOf(const YAML::Node& node) {
  if (!node.IsDefined()) return 0;
  const YAML::Mark mark = node.Mark();
  return mark.is_null() ? 0 : mark.line + 1;
}

void CollectLines(const YAML::Node& node, const std::string& path,
                  std::map<std::string, int>* lines) {
  if (node.IsMap()) {
    for (auto it = node.begin(); it != node.end(); ++it) {
      const YAML::Node key = it->first;
      if (!key.IsScalar()) continue;
      const std::string child = Join(path, key.Scalar());
      if (LineOf(key) > 0) lines->emplace(child, LineOf(key));
      CollectLines(it->second, child, lines);
    }
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      const std::string child = path + "[" + std::to_string(i) + "]";
      if (LineOf(node[i]) > 0) lines->emplace(child, LineOf(node[i]));
      CollectLines(node[i], child, lines);
    }
  }
}

}  // namespace

YamlNode YamlNode::Parse(const std::string& text, const std::string& source,
                         const std::string& hint) {
  auto origin = std::make_shared<const Origin>(Origin{source, hint});
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    ThrowInputError(source, ": invalid YAML (line ", e.mark.line + 1, "): ", e.msg, hint);
  }
  return YamlNode(std::move(origin), std::move(root), "");
}

YamlNode YamlNode::Load(const std::string& path, const std::string& hint) {
  return Parse(ReadRegularFile(path, kMaxTextFileBytes, hint), path, hint);
}

YamlNode YamlNode::WithNode(YAML::Node node) const { return YamlNode(origin_, node, path_); }

int YamlNode::line() const { return LineOf(node_); }

std::string YamlNode::LineNote() const {
  const int n = line();
  return n > 0 ? " (line " + std::to_string(n) + ")" : std::string();
}

std::string YamlNode::Describe() const {
  if (IsNull()) return "nothing";
  if (node_.IsMap()) return "a map";
  if (node_.IsSequence()) return "a list";
  return "'" + node_.Scalar() + "'";
}

bool YamlNode::Has(const std::string& key) const { return IsMap() && node_[key].IsDefined(); }

YamlNode YamlNode::operator[](const std::string& key) const {
  return YamlNode(origin_, IsMap() ? node_[key] : YAML::Node(YAML::NodeType::Undefined),
                  Join(path_, key));
}

YamlNode YamlNode::operator[](std::size_t i) const {
  return YamlNode(origin_, IsSequence() && i < node_.size() ? node_[i] : YAML::Node(),
                  path_ + "[" + std::to_string(i) + "]");
}

YamlNode YamlNode::Required(const std::string& key) const {
  if (!IsMap()) TypeError("a map");
  if (!Has(key))
    ThrowInputError(source(), ": missing key '", Join(path_, key), "'", LineNote(), hint());
  return (*this)[key];
}

void YamlNode::TypeError(const std::string& expected) const {
  Fail("expected ", expected, ", got ", Describe());
}

void YamlNode::CheckKeys(const std::set<std::string>& known, const std::string& note) const {
  if (!IsMap()) TypeError("a map");
  std::set<std::string> seen;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const YAML::Node key = it->first;
    const std::string line = LineOf(key) > 0 ? " (line " + std::to_string(LineOf(key)) + ")" : "";
    if (!key.IsScalar()) {
      ThrowInputError(source(), ": a key in '", Name(), "'", line, " is not a plain name", hint());
    }
    const std::string name = key.Scalar();
    if (!known.count(name)) {
      ThrowInputError(source(), ": unknown key '", Join(path_, name), "'", line, note, hint());
    }
    if (!seen.insert(name).second) {
      // yaml-cpp keeps the first of repeated keys; which one was meant is unknown.
      ThrowInputError(source(), ": duplicate key '", Join(path_, name), "'", line, hint());
    }
  }
}

std::string YamlNode::ChoicesNote(const std::set<std::string>& known) {
  std::string list;
  for (const std::string& key : known) list += (list.empty() ? "" : ", ") + key;
  return " (expected one of: " + list + ")";
}

std::map<std::string, int> YamlNode::KeyLines() const {
  std::map<std::string, int> lines;
  CollectLines(node_, path_, &lines);
  return lines;
}

long long YamlNode::ReadInteger(long long lo, long long hi, const char* expected) const {
  // Optional sign and decimal digits, in [lo, hi].
  const std::string s = IsScalar() ? node_.Scalar() : std::string();
  const std::size_t first = (!s.empty() && (s[0] == '+' || s[0] == '-')) ? 1 : 0;
  bool ok = first < s.size();
  for (std::size_t i = first; ok && i < s.size(); ++i) ok = s[i] >= '0' && s[i] <= '9';
  errno = 0;
  const long long v = ok ? std::strtoll(s.c_str(), nullptr, 10) : 0;
  if (!ok || errno == ERANGE || v < lo || v > hi) TypeError(expected);
  return v;
}

void YamlNode::Read(int* value, const char* expected) const {
  *value =
      static_cast<int>(ReadInteger(std::numeric_limits<int>::min(), std::numeric_limits<int>::max(),
                                   expected ? expected : "an integer"));
}

void YamlNode::Read(uint32_t* value, const char* expected) const {
  *value = static_cast<uint32_t>(ReadInteger(0, std::numeric_limits<uint32_t>::max(),
                                             expected ? expected : "an integer in 0..4294967295"));
}

void YamlNode::Read(uint64_t* value, const char* expected) const {
  *value = static_cast<uint64_t>(
      ReadInteger(0, std::numeric_limits<long long>::max(),
                  expected ? expected : "an integer in 0..9223372036854775807"));
}

void YamlNode::Read(double* value, const char* expected) const {
  if (!ParseFiniteNumber(node_, value)) TypeError(expected ? expected : "a finite number");
}

void YamlNode::Read(std::optional<double>* value, const char* expected) const {
  if (Is("auto")) {
    value->reset();
    return;
  }
  double v = 0.0;
  if (!ParseFiniteNumber(node_, &v)) TypeError(expected ? expected : "auto or a finite number > 0");
  *value = v;
}

void YamlNode::Read(bool* value, const char* expected) const {
  if (Is("true") || Is("True") || Is("TRUE")) {
    *value = true;
  } else if (Is("false") || Is("False") || Is("FALSE")) {
    *value = false;
  } else {
    TypeError(expected ? expected : "true or false");
  }
}

void YamlNode::Read(std::string* value, const char* expected) const {
  if (!IsScalar()) TypeError(expected ? expected : "a string");
  *value = node_.Scalar();
}

void YamlNode::Read(Eigen::Vector3d* value, const char* expected) const {
  const char* what = expected ? expected : "a list of 3 numbers";
  if (!IsSequence() || node_.size() != 3) TypeError(what);
  for (int k = 0; k < 3; ++k) {
    if (!ParseFiniteNumber(node_[k], &(*value)[k])) (*this)[k].TypeError("a finite number");
  }
}

}  // namespace banmo
