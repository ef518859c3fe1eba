#include "cli_options.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "banmo/util/error.h"

namespace banmo::tools {

std::vector<double> ParseNumberList(const std::string& flag, const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      ThrowInputError(flag, " '", text, "': '", item, "' is not a number");
    }
  }
  return v;
}

Eigen::Vector3d ParseVector3Option(const std::string& flag, const std::string& text) {
  const std::vector<double> v = ParseNumberList(flag, text);
  if (v.size() != 3 || !std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
    ThrowInputError(flag, " '", text, "': expected 3 finite numbers x,y,z");
  }
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

Eigen::AlignedBox3d ParseBoxOption(const std::string& flag, const std::string& text,
                                   const std::string& expected) {
  const std::vector<double> v = ParseNumberList(flag, text);
  if (v.size() != 6) ThrowInputError(flag, " '", text, "': expected ", expected);
  const Eigen::AlignedBox3d box(Eigen::Vector3d(v[0], v[1], v[2]),
                                Eigen::Vector3d(v[3], v[4], v[5]));
  if (!(box.sizes().array() > 0.0).all()) {
    ThrowInputError(flag, " '", text, "': expected max > min on every axis");
  }
  return box;
}

}  // namespace banmo::tools
