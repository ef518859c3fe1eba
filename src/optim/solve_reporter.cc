#include "banmo/optim/solve_reporter.h"

#include <glog/logging.h>

#include <cstdio>

namespace banmo {

void PrintingReporter::Report(const SolveMessage& message) {
  const std::string prefix = message.stage.empty() ? "" : "[" + message.stage + "] ";
  if (message.kind == SolveMessageKind::kWarning) {
    LOG(WARNING) << prefix << message.text;
    return;
  }
  std::printf("%s%s\n", prefix.c_str(), message.text.c_str());
  std::fflush(stdout);
}

}  // namespace banmo
