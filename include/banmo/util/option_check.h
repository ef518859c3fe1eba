// The option-checking idiom of the YAML-read options (docs/config.md): each
// options struct has a Check(const OptionChecker&, key) beside it that
// checks its own fields and throws InputError naming the file and the key
// path ("problems/x.yaml: stages[1].adam.lr: expected ..."); rules that span
// several structs are checked where they meet (e.g. CheckStageRules,
// optim/config.cc).
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "banmo/util/error.h"

namespace banmo {

class OptionChecker {
 public:
  // `source` names the file in every message; it must outlive the checker.
  explicit OptionChecker(const std::string& source) : source_(source) {}

  template <class... Args>
  [[noreturn]] void Fail(const std::string& key, Args&&... args) const {
    ThrowInputError(source_, ": ", key, ": ", std::forward<Args>(args)...);
  }
  void Positive(const std::string& key, double v) const {
    if (!(v > 0) || !std::isfinite(v)) Fail(key, "expected a finite number > 0, got ", v);
  }
  void Positive(const std::string& key, int v) const {
    if (v <= 0) Fail(key, "expected an integer > 0, got ", v);
  }
  void NonNegative(const std::string& key, double v) const {
    if (!(v >= 0) || !std::isfinite(v)) Fail(key, "expected a finite number >= 0, got ", v);
  }
  void NonNegative(const std::string& key, int v) const {
    if (v < 0) Fail(key, "expected an integer >= 0, got ", v);
  }
  // v in (0, max] (finite).
  void PositiveAtMost(const std::string& key, double v, double max) const {
    if (!(v > 0 && v <= max)) Fail(key, "expected a number in (0, ", max, "], got ", v);
  }
  void PositiveAtMost(const std::string& key, int v, int max) const {
    if (!(v > 0 && v <= max)) Fail(key, "expected an integer in [1, ", max, "], got ", v);
  }
  void Fraction(const std::string& key, double v) const {
    if (!(v >= 0 && v <= 1)) Fail(key, "expected a fraction in [0, 1], got ", v);
  }
  // key[i] for each i: fractions of a stage, strictly increasing.
  void IncreasingFractions(const std::string& key, const std::vector<double>& v) const {
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string item = key + "[" + std::to_string(i) + "]";
      Fraction(item, v[i]);
      if (i > 0 && !(v[i] > v[i - 1])) {
        Fail(item, "expected increasing fractions, got ", v[i], " after ", v[i - 1]);
      }
    }
  }

  // Fractions of a stage that schedule something at a batch
  // (StageConfig::BatchAt): one that rounds to the batch count would come
  // after the last batch and never run.
  void BatchFractions(const std::string& key, const std::vector<double>& v, int batches) const {
    IncreasingFractions(key, v);
    for (size_t i = 0; i < v.size(); ++i) {
      const long at = std::lround(v[i] * batches);
      if (at >= batches) {
        Fail(key + "[" + std::to_string(i) + "]", v[i], " of ", batches, " batches is batch ", at,
             ", after the stage's last batch (", batches - 1,
             "): it would never run; expected a fraction below ", (batches - 0.5) / batches);
      }
    }
  }

 private:
  const std::string& source_;
};

}  // namespace banmo
