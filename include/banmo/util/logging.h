// Logging and invariant checks behind one header, so that a later change of
// logging library touches one file. Use CHECK/DCHECK for internal invariants
// and banmo::InputError (util/error.h) for bad user input.
#pragma once

#include <glog/logging.h>  // IWYU pragma: export

namespace banmo {

// Initialises glog once for an executable: logs to stderr, no log files.
void InitLogging(const char* argv0);

}  // namespace banmo
