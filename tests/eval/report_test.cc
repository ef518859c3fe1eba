// eval/report.h: per_frame.csv, summary.json and the console table.
#include "banmo/eval/report.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace banmo {
namespace {

// Two frames with known metrics; frame 1 is the worse.
EvalReport TwoFrameReport() {
  EvalReport report;
  for (int i = 0; i < 2; ++i) {
    FrameEval f;
    f.pred_name = i == 0 ? "pred/0000.ply" : "pred/a,b \"quoted\".ply";
    f.gt_name = "gt/000" + std::to_string(i) + ".ply";
    f.num_pred_points = 100 + i;
    f.num_gt_points = 200 + i;
    f.initial_scale = 1.5;
    f.icp.source_to_target.scale = 2.0;
    f.icp.iterations = 7 + i;
    f.icp.converged = i == 0;
    f.metrics.pred_to_gt = 0.01 * (i + 1);
    f.metrics.gt_to_pred = 0.02 * (i + 1);
    f.metrics.chamfer_sum = 0.03 * (i + 1);
    f.metrics.chamfer_mean = 0.015 * (i + 1);
    f.metrics.fscore = {0.5 - 0.1 * i, 0.7 - 0.1 * i, 0.9 - 0.1 * i};
    f.metrics.precision = {0.4, 0.6, 0.8};
    f.metrics.recall = {0.6, 0.8, 1.0};
    report.frames.push_back(f);
  }
  report.chamfer_cm = 4.5;
  report.chamfer_mean_cm = 2.25;
  report.fscore_percent = {45, 65, 85};
  report.worst_chamfer_frame = 1;
  report.worst_fscore_frame = {1, 1, 1};
  report.icp_converged_frames = 1;
  return report;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream is(text);
  for (std::string line; std::getline(is, line);) lines.push_back(line);
  return lines;
}

TEST(FormatPerFrameCsv, OneRowPerFrameUnderTheDocumentedHeader) {
  const std::vector<std::string> lines = Lines(FormatPerFrameCsv(TwoFrameReport()));
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(lines[0],
            "frame,pred,gt,chamfer_cm,chamfer_mean_cm,pred_to_gt_cm,gt_to_pred_cm,fscore_1,"
            "fscore_2,fscore_5,precision_1,precision_2,precision_5,recall_1,recall_2,recall_5,"
            "initial_scale,icp_scale,icp_iterations,icp_converged,icp_rmse_initial,icp_rmse_final,"
            "num_pred_points,num_gt_points,gt_normalization");
  EXPECT_EQ(lines[1],
            "0,pred/0000.ply,gt/0000.ply,3,1.5,1,2,50,70,90,40,60,80,60,80,100,1.5,2,7,1,0,0,100,"
            "200,1");
  // A name with a comma or quote is quoted (RFC 4180).
  EXPECT_EQ(lines[2].rfind("1,\"pred/a,b \"\"quoted\"\".ply\",gt/0001.ply,6,3,2,4,40,60,80,", 0),
            0u)
      << lines[2];
}

TEST(FormatSummaryJson, MeansWorstFramesAndOptions) {
  EvalOptions options;
  options.icp_iterations = 17;
  const std::string json = FormatSummaryJson(TwoFrameReport(), options);
  for (const char* expected :
       {"\"frames\": 2,", "\"chamfer_cm\": 4.5,", "\"chamfer_mean_cm\": 2.25,", "\"fscore_2\": 65,",
        "\"icp_converged_frames\": 1,", "\"worst_frame\": {\"frame\": 1,",
        "\"pred\": \"pred/a,b \\\"quoted\\\".ply\"", "\"fscore_1\": {\"frame\": 1, \"value\": 40}",
        "\"icp_iterations\": 17"}) {
    EXPECT_NE(json.find(expected), std::string::npos) << expected << " in\n" << json;
  }
  EXPECT_EQ(json.front(), '{');
  EXPECT_EQ(json.substr(json.size() - 2), "}\n");
  // No frames: no worst_frame entry.
  EvalReport empty;
  EXPECT_EQ(FormatSummaryJson(empty, options).find("worst_frame"), std::string::npos);
}

TEST(FormatReportTable, FrameLinesThenMeanAndWorst) {
  const std::vector<std::string> lines = Lines(FormatReportTable(TwoFrameReport()));
  // protocol, header, 2 frames, mean, worst, ICP line.
  ASSERT_EQ(lines.size(), 7u);
  EXPECT_EQ(lines[0].rfind("protocol: banmo", 0), 0u) << lines[0];
  EXPECT_NE(lines[2].find("0000.ply"), std::string::npos);
  EXPECT_NE(lines[2].find("3.000"), std::string::npos);
  EXPECT_EQ(lines[2].back(), '7');                       // converged: no star
  EXPECT_EQ(lines[3].back(), '*');                       // frame 1 did not converge
  EXPECT_NE(lines[3].find("3.000"), std::string::npos);  // scale 1.5 x 2
  EXPECT_EQ(lines[4].rfind("mean", 0), 0u);
  EXPECT_NE(lines[4].find("4.500"), std::string::npos);
  EXPECT_EQ(lines[5].rfind("worst (CD: frame 1, F: min)", 0), 0u);
  EXPECT_EQ(lines[6],
            "ICP converged in 1 of 2 frames (* = not converged within the iteration limit)");
}

TEST(WriteEvalOutputs, WritesBothFilesIntoANewFolder) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "banmo_report_test" / "nested";
  std::filesystem::remove_all(dir.parent_path());
  const EvalReport report = TwoFrameReport();
  WriteEvalOutputs(dir.string(), report, EvalOptions());
  std::ifstream csv(dir / "per_frame.csv"), json(dir / "summary.json");
  std::stringstream csv_text, json_text;
  csv_text << csv.rdbuf();
  json_text << json.rdbuf();
  EXPECT_EQ(csv_text.str(), FormatPerFrameCsv(report));
  EXPECT_EQ(json_text.str(), FormatSummaryJson(report, EvalOptions()));
  std::filesystem::remove_all(dir.parent_path());
}

}  // namespace
}  // namespace banmo
