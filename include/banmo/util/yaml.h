// The one YAML walker of the project: the solver config, the model file, the
// dataset manifest and the rig files read and write through it.
//
// A YamlNode is a yaml-cpp node together with where it came from: the source
// (the file, named in every message), the key path ("stages[1].adam.lr") and
// its line. Its reads are strict and typed: integers are decimal digits in
// the type's range, numbers are finite (classic locale, so "1,5" is refused
// in every locale), booleans are true/false, enums are read by their names
// (util/enum_names.h) and structs through the field list they expose
// (VisitFields(visitor, s), found by argument-dependent lookup), with unknown
// and repeated keys refused. Every error is an InputError (exit 2):
//   <source>: key '<path>' (line N): expected <what>, got <what was there>
//   <source>: <path>: expected one of {a, b}, got 'c' (line N)   (enums)
//   <source>: unknown key '<path>' (line N)
//   <source>: missing key '<path>' (line N)
// YamlWriter is the counterpart: it writes the same field lists back, so a
// field is read and written under the same key by construction.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "banmo/util/enum_names.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"

namespace banmo {

class YamlNode {
 public:
  // Parses `text`. A syntax error is an InputError
  // "<source>: invalid YAML (line N): <what>"; `hint` (e.g. what to do) is
  // appended to this and to every later message about the document.
  static YamlNode Parse(const std::string& text, const std::string& source,
                        const std::string& hint = "");
  // Reads the regular file `path` (util/input_file.h, at most
  // kMaxTextFileBytes) and parses it; the path is the source.
  static YamlNode Load(const std::string& path, const std::string& hint = "");

  // `node` in place of this one, under the same source and key path (for a
  // map the caller rewrote).
  YamlNode WithNode(YAML::Node node) const;

  const std::string& source() const { return origin_->source; }
  const std::string& hint() const { return origin_->hint; }
  const std::string& path() const { return path_; }
  const YAML::Node& yaml() const { return node_; }
  // The node's line (1-based), 0 if unknown (an absent key).
  int line() const;
  // " (line N)", or "" when the line is unknown.
  std::string LineNote() const;
  // The key path, "(top level)" for the document itself.
  std::string Name() const { return path_.empty() ? "(top level)" : path_; }
  // For messages: "nothing", "a map", "a list" or the quoted scalar.
  std::string Describe() const;

  bool IsDefined() const { return node_.IsDefined(); }
  bool IsNull() const { return !node_.IsDefined() || node_.IsNull(); }
  bool IsMap() const { return node_.IsDefined() && node_.IsMap(); }
  bool IsSequence() const { return node_.IsDefined() && node_.IsSequence(); }
  bool IsScalar() const { return node_.IsDefined() && node_.IsScalar(); }
  // True if this is the scalar `text`.
  bool Is(const std::string& text) const { return IsScalar() && node_.Scalar() == text; }

  // True if this is a map with `key` (an empty value counts).
  bool Has(const std::string& key) const;
  // node[key] with path "<path>.key"; undefined when absent or not a map.
  YamlNode operator[](const std::string& key) const;
  // Element i of a list, path "<path>[i]".
  YamlNode operator[](std::size_t i) const;
  // Elements of a list (0 when not a list).
  std::size_t size() const { return IsSequence() ? node_.size() : 0; }
  // node[key], which must be present ("missing key" otherwise; this map's
  // line).
  YamlNode Required(const std::string& key) const;

  // Throws "<source>: key '<path>' (line N): <args...>" (and the hint).
  template <class... Args>
  [[noreturn]] void Fail(Args&&... args) const {
    ThrowInputError(source(), ": key '", Name(), "'", LineNote(), ": ", std::forward<Args>(args)...,
                    hint());
  }
  // Throws "<source>: key '<path>' (line N): expected <expected>, got ...".
  [[noreturn]] void TypeError(const std::string& expected) const;

  // This must be a map whose keys are plain names, each once and each in
  // `known`; `note` follows an unknown key's message.
  void CheckKeys(const std::set<std::string>& known, const std::string& note = "") const;
  // " (expected one of: a, b, c)", a note for CheckKeys.
  static std::string ChoicesNote(const std::set<std::string>& known);
  // The line (1-based) of every key and list element below this node, by
  // key path ("stages[1].adam.lr").
  std::map<std::string, int> KeyLines() const;

  // Typed reads. `expected` replaces the default description of the value
  // in the message ("a positive integer" for "an integer").
  void Read(int* value, const char* expected = nullptr) const;
  void Read(uint32_t* value, const char* expected = nullptr) const;
  void Read(uint64_t* value, const char* expected = nullptr) const;
  // A finite number.
  void Read(double* value, const char* expected = nullptr) const;
  // `auto` (nothing) or a finite number; described as "auto or a finite
  // number > 0", since every such option is a positive size (its Check()
  // refuses the rest).
  void Read(std::optional<double>* value, const char* expected = nullptr) const;
  void Read(bool* value, const char* expected = nullptr) const;
  void Read(std::string* value, const char* expected = nullptr) const;
  // A list of 3 finite numbers.
  void Read(Eigen::Vector3d* value, const char* expected = nullptr) const;
  // A list replaces the current list entirely; an empty value (`key:`) is
  // the empty list.
  template <class T>
  void Read(std::vector<T>* value, const char* expected = nullptr) const;
  // An enum by its name, or a struct by its field list.
  template <class T>
  void Read(T* value, const char* expected = nullptr) const;

  template <class T>
  T As(const char* expected = nullptr) const {
    T value{};
    Read(&value, expected);
    return value;
  }
  // Reads node[key] into *value if the key is present; returns whether it was.
  template <class T>
  bool ReadIfPresent(const std::string& key, T* value) const {
    if (!Has(key)) return false;
    (*this)[key].Read(value);
    return true;
  }
  // node[key] if the key is present, else `fallback`.
  template <class T>
  T ValueOr(const std::string& key, T fallback) const {
    ReadIfPresent(key, &fallback);
    return fallback;
  }
  template <class T>
  void ReadRequired(const std::string& key, T* value) const {
    Required(key).Read(value);
  }

  // A map over a struct: the keys present override the struct's current
  // values (its defaults); an empty value keeps them all.
  template <class S>
  void ReadStruct(S* value) const;

 private:
  struct Origin {
    std::string source;
    std::string hint;
  };
  YamlNode(std::shared_ptr<const Origin> origin, YAML::Node node, std::string path)
      : origin_(std::move(origin)), node_(std::move(node)), path_(std::move(path)) {}

  long long ReadInteger(long long lo, long long hi, const char* expected) const;

  // Reads the present keys of a map into a struct's fields.
  struct FieldReader {
    const YamlNode& map;
    template <class T>
    void operator()(const char* key, T& value) {
      if (map.Has(key)) map[key].Read(&value);
    }
  };
  struct KeyCollector {
    std::set<std::string> keys;
    template <class T>
    void operator()(const char* key, T&) {
      keys.insert(key);
    }
  };

  std::shared_ptr<const Origin> origin_;
  YAML::Node node_;
  std::string path_;
};

template <class T>
void YamlNode::Read(std::vector<T>* value, const char* expected) const {
  if (IsNull()) {
    value->clear();
    return;
  }
  if (!IsSequence()) TypeError(expected ? expected : "a list");
  std::vector<T> out(node_.size());
  for (std::size_t i = 0; i < out.size(); ++i) (*this)[i].Read(&out[i]);
  *value = std::move(out);
}

template <class T>
void YamlNode::Read(T* value, const char* expected) const {
  if constexpr (std::is_enum_v<T>) {
    const std::optional<T> v = IsScalar() ? ParseEnum<T>(node_.Scalar()) : std::nullopt;
    if (!v) {
      ThrowInputError(source(), ": ", Name(), ": expected one of ", EnumChoices<T>(), ", got ",
                      Describe(), LineNote(), hint());
    }
    *value = *v;
  } else {
    ReadStruct(value);
  }
}

template <class S>
void YamlNode::ReadStruct(S* value) const {
  if (IsNull()) return;
  if (!IsMap()) TypeError("a map");
  KeyCollector collector;
  VisitFields(collector, *value);
  CheckKeys(collector.keys);
  FieldReader reader{*this};
  VisitFields(reader, *value);
}

namespace internal {
template <class T>
struct IsVector : std::false_type {};
template <class T, class A>
struct IsVector<std::vector<T, A>> : std::true_type {};
}  // namespace internal

// Which structs YamlWriter writes on one line ({a: 1, b: 2}): none here; a
// writer's Layout has `template <class S> static constexpr bool kOneLine`.
struct YamlBlockLayout {
  template <class S>
  static constexpr bool kOneLine = false;
};

// Writes values and structs (by their field lists) into a YAML::Emitter:
// numbers in the shortest form that reads back exactly (FormatDouble),
// booleans as true/false, enums by name, lists of values on one line,
// `auto` for an empty optional.
template <class Layout = YamlBlockLayout>
class YamlWriter {
 public:
  explicit YamlWriter(YAML::Emitter* out) : out_(*out) {}

  // One key and its value (the field-list visitor).
  template <class T>
  void operator()(const char* key, T& value) {
    out_ << YAML::Key << key << YAML::Value;
    Write(value);
  }

  // Any value the reader reads (a struct through its field list; the
  // visitor only reads the fields).
  template <class T>
  void Write(const T& v) {
    if constexpr (std::is_enum_v<T>) {
      out_ << EnumName(v);
    } else if constexpr (std::is_same_v<T, bool>) {
      out_ << (v ? "true" : "false");
    } else if constexpr (std::is_integral_v<T>) {
      out_ << v;
    } else if constexpr (std::is_same_v<T, double>) {
      out_ << FormatDouble(v);
    } else if constexpr (std::is_same_v<T, std::optional<double>>) {
      if (v) {
        Write(*v);
      } else {
        out_ << "auto";
      }
    } else if constexpr (std::is_same_v<T, std::string>) {
      // Strings YAML would read as null are quoted; the reader takes any
      // other scalar as a string.
      if (v.empty() || v == "~" || v == "null" || v == "Null" || v == "NULL") {
        out_ << YAML::DoubleQuoted << v;
      } else {
        out_ << v;
      }
    } else if constexpr (std::is_same_v<T, Eigen::Vector3d>) {
      out_ << YAML::Flow << YAML::BeginSeq;
      for (int k = 0; k < 3; ++k) Write(v[k]);
      out_ << YAML::EndSeq;
    } else if constexpr (internal::IsVector<T>::value) {
      using E = typename T::value_type;
      // Lists of values on one line, lists of structs one per line.
      if (std::is_arithmetic_v<E> || std::is_enum_v<E> || std::is_same_v<E, std::string>) {
        out_ << YAML::Flow;
      }
      out_ << YAML::BeginSeq;
      for (const auto& x : v) Write(static_cast<typename T::value_type>(x));
      out_ << YAML::EndSeq;
    } else {
      if (Layout::template kOneLine<T>) out_ << YAML::Flow;
      out_ << YAML::BeginMap;
      VisitFields(*this, const_cast<T&>(v));
      out_ << YAML::EndMap;
    }
  }

 private:
  YAML::Emitter& out_;
};

}  // namespace banmo
