#include "banmo/util/reporter.h"

#include <cstdio>

namespace banmo {

void StdoutLineReporter::Report(const ReportedLine& line) {
  std::printf("%s: %s%s\n", prefix_.c_str(), line.level == ReportLevel::kWarning ? "warning: " : "",
              line.text.c_str());
}

}  // namespace banmo
