// Outputs of an evaluation: per_frame.csv, summary.json and a console table.
#pragma once

#include <string>

#include "banmo/eval/evaluate.h"

namespace banmo {

// One row per frame: frame, pred, gt, chamfer_cm, chamfer_mean_cm,
// pred_to_gt_cm, gt_to_pred_cm, fscore_1, fscore_2, fscore_5 (percent),
// precision_*/recall_* (percent), initial_scale, icp_scale, icp_iterations,
// icp_converged, icp_rmse_initial, icp_rmse_final, num_pred_points,
// num_gt_points, gt_normalization.
std::string FormatPerFrameCsv(const EvalReport& report);

// A JSON object with at least protocol, frames, chamfer_cm, chamfer_mean_cm,
// fscore_1, fscore_2, fscore_5, worst_frame, worst_fscore_frames (see docs/eval.md).
// `options` are echoed under "options".
std::string FormatSummaryJson(const EvalReport& report, const EvalOptions& options);

// A fixed-width table (one line per frame, then mean and worst lines).
std::string FormatReportTable(const EvalReport& report);

// Writes per_frame.csv and summary.json into `dir` (created if missing),
// both through one StagedOutput (util/atomic_file.h): they appear together.
void WriteEvalOutputs(const std::string& dir, const EvalReport& report, const EvalOptions& options);

}  // namespace banmo
