// Option parsers shared by several subcommands.
#pragma once

#include <Eigen/Geometry>
#include <string>

namespace banmo::tools {

// A box option "xmin,ymin,zmin,xmax,ymax,zmax" (e.g. --bounds). Throws
// InputError naming `flag` and `text` unless it is 6 numbers with max > min on
// every axis; `expected` says what the option accepts.
Eigen::AlignedBox3d ParseBoxOption(
    const std::string& flag, const std::string& text,
    const std::string& expected = "6 numbers xmin,ymin,zmin,xmax,ymax,zmax");

}  // namespace banmo::tools
