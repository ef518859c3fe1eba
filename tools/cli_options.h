// Option parsers shared by several subcommands.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace banmo::tools {

// A comma-separated list of numbers. Throws InputError naming `flag`, `text`
// and the item that is not a number.
std::vector<double> ParseNumberList(const std::string& flag, const std::string& text);

// A vector option "x,y,z" (e.g. synth --root-offset): 3 finite numbers.
Eigen::Vector3d ParseVector3Option(const std::string& flag, const std::string& text);

// A box option "xmin,ymin,zmin,xmax,ymax,zmax" (e.g. --bounds). Throws
// InputError naming `flag` and `text` unless it is 6 numbers with max > min on
// every axis; `expected` says what the option accepts.
Eigen::AlignedBox3d ParseBoxOption(
    const std::string& flag, const std::string& text,
    const std::string& expected = "6 numbers xmin,ymin,zmin,xmax,ymax,zmax");

}  // namespace banmo::tools
