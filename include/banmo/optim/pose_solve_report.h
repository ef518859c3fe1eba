// What the per-frame pose solves did (optim/pose_solve.h), without the
// Ceres headers: the solver's result and its summary carry these.
#pragma once

#include <string>
#include <vector>

namespace banmo {

// What one frame's solve did. Costs are Ceres' 1/2 sum rho(|r|^2) over the
// frame's rays and composite terms, divided by the number of rays.
struct FramePoseSolve {
  int video = 0;
  int frame = 0;
  double cost_before = 0.0;
  double cost_after = 0.0;
  int iterations = 0;         // LM iterations (all solves of the frame)
  bool searched = false;      // the multi-hypothesis search ran
  int candidates = 0;         // candidate poses whose cost was evaluated
  bool replaced = false;      // a search candidate beat the local solve
  double rotation_deg = 0.0;  // rotation of the frame's root pose by the solve
  double seconds = 0.0;
};

struct PoseSolveReport {
  int stage = 0;  // when it ran: stage index and batch
  int batch = 0;
  std::vector<FramePoseSolve> frames;
  double seconds = 0.0;
  // Medians over the frames, and how many were searched / replaced.
  double median_cost_before = 0.0;
  double median_cost_after = 0.0;
  int searched = 0;
  int replaced = 0;
  // One line for the progress output.
  std::string Describe() const;
};

}  // namespace banmo
