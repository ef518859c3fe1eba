#include "banmo/eval/report.h"

#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>

#include "banmo/util/atomic_file.h"

namespace banmo {
namespace {

std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.10g", v);
  return buf;
}

std::string JsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

// CSV field: quoted when it holds a comma, quote or newline (RFC 4180).
std::string CsvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string BaseName(const std::string& path) {
  const std::string name = std::filesystem::path(path).filename().string();
  return name.empty() ? path : name;
}

constexpr const char* kFscoreKeys[3] = {"fscore_1", "fscore_2", "fscore_5"};

}  // namespace

std::string FormatPerFrameCsv(const EvalReport& report) {
  std::ostringstream os;
  os << "frame,pred,gt,chamfer_cm,chamfer_mean_cm,pred_to_gt_cm,gt_to_pred_cm,"
        "fscore_1,fscore_2,fscore_5,precision_1,precision_2,precision_5,"
        "recall_1,recall_2,recall_5,initial_scale,icp_scale,icp_iterations,icp_converged,"
        "icp_rmse_initial,icp_rmse_final,num_pred_points,num_gt_points,gt_normalization\n";
  for (std::size_t i = 0; i < report.frames.size(); ++i) {
    const FrameEval& f = report.frames[i];
    const DistanceMetrics& m = f.metrics;
    os << i << ',' << CsvField(f.pred_name) << ',' << CsvField(f.gt_name) << ','
       << Num(f.ChamferCm()) << ',' << Num(f.ChamferMeanCm()) << ',' << Num(100.0 * m.pred_to_gt)
       << ',' << Num(100.0 * m.gt_to_pred);
    for (double v : m.fscore) os << ',' << Num(100.0 * v);
    for (double v : m.precision) os << ',' << Num(100.0 * v);
    for (double v : m.recall) os << ',' << Num(100.0 * v);
    os << ',' << Num(f.initial_scale) << ',' << Num(f.icp.source_to_target.scale) << ','
       << f.icp.iterations << ',' << (f.icp.converged ? 1 : 0) << ',' << Num(f.icp.initial_rmse)
       << ',' << Num(f.icp.final_rmse) << ',' << f.num_pred_points << ',' << f.num_gt_points << ','
       << Num(f.gt_normalization) << '\n';
  }
  return os.str();
}

std::string FormatSummaryJson(const EvalReport& report, const EvalOptions& options) {
  std::ostringstream os;
  os << "{\n";
  os << "  \"protocol\": " << JsonString(EvalProtocolName(report.protocol)) << ",\n";
  os << "  \"frames\": " << report.frames.size() << ",\n";
  os << "  \"chamfer_cm\": " << Num(report.chamfer_cm) << ",\n";
  os << "  \"chamfer_mean_cm\": " << Num(report.chamfer_mean_cm) << ",\n";
  os << "  \"pred_to_gt_cm\": " << Num(report.pred_to_gt_cm) << ",\n";
  os << "  \"gt_to_pred_cm\": " << Num(report.gt_to_pred_cm) << ",\n";
  for (int k = 0; k < 3; ++k) {
    os << "  \"" << kFscoreKeys[k] << "\": " << Num(report.fscore_percent[k]) << ",\n";
  }
  os << "  \"icp_converged_frames\": " << report.icp_converged_frames << ",\n";
  if (report.worst_chamfer_frame >= 0) {
    const FrameEval& w = report.frames[static_cast<std::size_t>(report.worst_chamfer_frame)];
    os << "  \"worst_frame\": {\"frame\": " << report.worst_chamfer_frame
       << ", \"pred\": " << JsonString(w.pred_name) << ", \"gt\": " << JsonString(w.gt_name)
       << ", \"chamfer_cm\": " << Num(w.ChamferCm());
    for (int k = 0; k < 3; ++k) {
      os << ", \"" << kFscoreKeys[k] << "\": " << Num(100.0 * w.metrics.fscore[k]);
    }
    os << "},\n";
    os << "  \"worst_fscore_frames\": {";
    for (int k = 0; k < 3; ++k) {
      const int i = report.worst_fscore_frame[k];
      os << (k ? ", " : "") << "\"" << kFscoreKeys[k] << "\": {\"frame\": " << i << ", \"value\": "
         << Num(100.0 * report.frames[static_cast<std::size_t>(i)].metrics.fscore[k]) << "}";
    }
    os << "},\n";
  }
  os << "  \"units\": {\"chamfer\": \"cm = 100 x units where the GT's largest half-extent is 1\", "
        "\"fscore\": \"percent\"},\n";
  os << "  \"options\": {\"protocol\": " << JsonString(EvalProtocolName(options.protocol))
     << ", \"icp_iterations\": " << options.icp_iterations
     << ", \"icp_relative_tolerance\": " << Num(options.icp_relative_tolerance)
     << ", \"robust\": " << JsonString(RobustLossName(options.robust))
     << ", \"trim_fraction\": " << Num(options.trim_fraction)
     << ", \"huber_factor\": " << Num(options.huber_factor)
     << ", \"num_samples\": " << options.num_samples
     << ", \"dense_samples\": " << options.dense_samples
     << ", \"dense_icp_queries\": " << options.dense_icp_queries
     << ", \"icp_max_queries\": " << options.icp_max_queries << ", \"seed\": " << options.seed
     << ", \"symmetric_icp\": " << (options.symmetric_icp ? "true" : "false")
     << ", \"max_scale_change\": " << Num(options.max_scale_change)
     << ", \"gt_mode\": " << JsonString(GtModeName(options.gt_mode))
     << ", \"gt_max_edge\": " << Num(options.gt_max_edge) << "}\n";
  os << "}\n";
  return os.str();
}

std::string FormatReportTable(const EvalReport& report) {
  std::ostringstream os;
  char line[512];
  std::snprintf(line, sizeof(line), "%-5s %-28s %10s %10s %7s %7s %7s %6s %5s\n", "frame", "pred",
                "CD(cm)", "CDmean", "F@1%", "F@2%", "F@5%", "scale", "icp");
  os << "protocol: " << EvalProtocolName(report.protocol);
  if (report.protocol == EvalProtocol::kBanmo) {
    os << ", ground truth " << GtModeName(report.gt_mode)
       << (report.gt_mode == GtMode::kDense ? " (surfaces, docs/eval.md)"
                                            : " (vertices, BANMo's script)");
  }
  os << "\n" << line;
  for (std::size_t i = 0; i < report.frames.size(); ++i) {
    const FrameEval& f = report.frames[i];
    std::string name = BaseName(f.pred_name);
    if (name.size() > 28) name = "..." + name.substr(name.size() - 25);
    std::snprintf(line, sizeof(line), "%-5zu %-28s %10.3f %10.3f %7.1f %7.1f %7.1f %6.3f %3d%s\n",
                  i, name.c_str(), f.ChamferCm(), f.ChamferMeanCm(), 100.0 * f.metrics.fscore[0],
                  100.0 * f.metrics.fscore[1], 100.0 * f.metrics.fscore[2],
                  f.initial_scale * f.icp.source_to_target.scale, f.icp.iterations,
                  f.icp.converged ? "" : "*");
    os << line;
  }
  std::snprintf(line, sizeof(line), "%-34s %10.3f %10.3f %7.1f %7.1f %7.1f\n", "mean",
                report.chamfer_cm, report.chamfer_mean_cm, report.fscore_percent[0],
                report.fscore_percent[1], report.fscore_percent[2]);
  os << line;
  if (report.worst_chamfer_frame >= 0) {
    const auto& fr = report.frames;
    const FrameEval& w = fr[static_cast<std::size_t>(report.worst_chamfer_frame)];
    std::snprintf(
        line, sizeof(line), "%-34s %10.3f %10s %7.1f %7.1f %7.1f\n",
        ("worst (CD: frame " + std::to_string(report.worst_chamfer_frame) + ", F: min)").c_str(),
        w.ChamferCm(), "",
        100.0 * fr[static_cast<std::size_t>(report.worst_fscore_frame[0])].metrics.fscore[0],
        100.0 * fr[static_cast<std::size_t>(report.worst_fscore_frame[1])].metrics.fscore[1],
        100.0 * fr[static_cast<std::size_t>(report.worst_fscore_frame[2])].metrics.fscore[2]);
    os << line;
  }
  os << "ICP converged in " << report.icp_converged_frames << " of " << report.frames.size()
     << " frames (* = not converged within the iteration limit)\n";
  return os.str();
}

void WriteEvalOutputs(const std::string& dir, const EvalReport& report,
                      const EvalOptions& options) {
  // Both files appear together (docs/robustness.md): a killed run leaves
  // neither a new per_frame.csv beside an old summary.json nor the reverse.
  StagedOutput staged(dir, "eval");
  const std::filesystem::path base(staged.path());
  WriteFileAtomic((base / "per_frame.csv").string(), FormatPerFrameCsv(report));
  WriteFileAtomic((base / "summary.json").string(), FormatSummaryJson(report, options));
  staged.Commit();
}

}  // namespace banmo
