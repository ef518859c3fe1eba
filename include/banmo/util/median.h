// The median of a sample, as the solver's robust statistics use it.
#pragma once

#include <algorithm>
#include <vector>

namespace banmo {

// The upper median (the element at index n / 2 of the sorted values; no
// averaging for even n), 0 for an empty sample. Takes a copy: the order of
// the caller's values is kept.
inline double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace banmo
