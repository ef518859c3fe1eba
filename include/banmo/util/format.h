// Number formatting shared by the YAML writers (config, checkpoint).
#pragma once

#include <string>

namespace banmo {

// The shortest decimal (15 to 17 significant digits) that reads back
// (strtod) to exactly v, so written configs and checkpoints round-trip.
std::string FormatDouble(double v);

}  // namespace banmo
