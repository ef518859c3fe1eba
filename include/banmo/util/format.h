// Number formatting shared by the YAML writers (config, checkpoint) and
// printf-style text for messages (the solver's reporter).
#pragma once

#include <string>

namespace banmo {

// The shortest decimal (15 to 17 significant digits) that reads back
// (strtod) to exactly v, so written configs and checkpoints round-trip.
std::string FormatDouble(double v);

// std::snprintf into a std::string of any length.
std::string StrPrintf(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace banmo
