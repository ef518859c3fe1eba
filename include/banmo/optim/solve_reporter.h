// What the solver says while it runs (docs/solver.md, "Progress
// output"): stage starts and ends, progress lines, the summaries of the
// schedules' events (bone registration, pose solves, automatic sizing, held
// bounds refreshes, the density switch) and warnings all go through one
// SolveReporter (SolveOptions::reporter), as Ceres' IterationCallback: the
// stage loop prints nothing itself, and tests read what was reported.
#pragma once

#include <string>
#include <vector>

namespace banmo {

enum class SolveMessageKind {
  kStage,    // a stage starts, ends or stops
  kBatch,    // a progress line (every stage.log_every batches and the last)
  kEvent,    // a schedule's event: its summary
  kWarning,  // something may be wrong (reported also with SolveOptions::quiet)
};

struct SolveMessage {
  SolveMessageKind kind = SolveMessageKind::kEvent;
  std::string stage;  // the stage's name (empty: none)
  int batch = 0;      // batches done in the stage when it was said
  std::string text;   // one line, without the stage's name or a newline
};

class SolveReporter {
 public:
  virtual ~SolveReporter() = default;
  virtual void Report(const SolveMessage& message) = 0;
};

// `banmo solve`'s reporter: "[stage] text" lines on stdout, flushed; warnings
// through glog's LOG(WARNING) (stderr).
class PrintingReporter : public SolveReporter {
 public:
  void Report(const SolveMessage& message) override;
};

// Keeps every message (tests).
class RecordingReporter : public SolveReporter {
 public:
  void Report(const SolveMessage& message) override { messages.push_back(message); }
  std::vector<SolveMessage> messages;
};

}  // namespace banmo
