// Lines a library step says while it runs (root-pose initialisation's
// summaries and warnings): the step reports each line to a LineReporter
// instead of printing, so the caller chooses where lines go (stdout with
// a prefix, nowhere) and tests read what was reported. The solver's own,
// richer interface is optim/solve_reporter.h.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace banmo {

enum class ReportLevel {
  kInfo,     // a summary
  kWarning,  // something may be wrong
};

struct ReportedLine {
  ReportLevel level = ReportLevel::kInfo;
  std::string text;  // one line, without a newline
};

class LineReporter {
 public:
  virtual ~LineReporter() = default;
  virtual void Report(const ReportedLine& line) = 0;
  void Info(const std::string& text) { Report({ReportLevel::kInfo, text}); }
  void Warning(const std::string& text) { Report({ReportLevel::kWarning, text}); }
};

// "<prefix>: <text>" lines on stdout; warnings read "<prefix>: warning: <text>".
class StdoutLineReporter : public LineReporter {
 public:
  explicit StdoutLineReporter(std::string prefix) : prefix_(std::move(prefix)) {}
  void Report(const ReportedLine& line) override;

 private:
  std::string prefix_;
};

// Keeps every line (tests).
class RecordingLineReporter : public LineReporter {
 public:
  void Report(const ReportedLine& line) override { lines.push_back(line); }
  std::vector<ReportedLine> lines;
};

}  // namespace banmo
