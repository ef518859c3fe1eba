// Names of option enums, in one table per enum: configs and command lines
// parse them here (ParseEnum), writers print them (EnumName), and errors list
// the choices (EnumChoices). An enum opts in by specialising EnumNames:
//
//   template <> struct EnumNames<StepRule> {
//     static constexpr std::pair<StepRule, const char*> kNames[] = {
//         {StepRule::kAdam, "adam"}, {StepRule::kLm, "lm"}};
//   };
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>

namespace banmo {

template <class E>
struct EnumNames;  // specialised per enum: kNames, every value once

template <class E, class = void>
struct HasEnumNames : std::false_type {};
template <class E>
struct HasEnumNames<E, std::void_t<decltype(EnumNames<E>::kNames)>> : std::true_type {};

// The name of `value` ("?" for a value missing from the table).
template <class E>
const char* EnumName(E value) {
  for (const auto& [v, name] : EnumNames<E>::kNames) {
    if (v == value) return name;
  }
  return "?";
}

// The value named `name`, exactly (case-sensitive), or nothing.
template <class E>
std::optional<E> ParseEnum(std::string_view name) {
  for (const auto& [v, n] : EnumNames<E>::kNames) {
    if (name == n) return v;
  }
  return std::nullopt;
}

// "{a, b, c}" for error messages.
template <class E>
std::string EnumChoices() {
  std::string out = "{";
  for (const auto& [v, name] : EnumNames<E>::kNames) {
    if (out.size() > 1) out += ", ";
    out += name;
  }
  return out + "}";
}

}  // namespace banmo
