// Per-frame root-pose solves (docs/solver.md, "Pose solves").
//
// A minibatch sees a few rays of each frame, too few for a second-order
// step on that frame's pose. A pose solve turns this round: frame by frame,
// it samples many rays of ONE frame, holds every other block constant (the
// fields, the bones, the other frames), and runs a few Levenberg-Marquardt
// iterations on the frame's root correction dG^t (6 degrees of freedom,
// G^t = G0^t dG^t) and, with `pose_solve.bones`, its bone transforms J_b^t
// (6 B more) with the stage's composite terms and robust losses. The
// batch skips the MLP-weight Jacobians (RayBatch::SetFieldJacobians), so an
// iteration costs about one forward pass of the frame's rays.
//
// Frames whose cost stays high after their solve (search_ratio times the
// median frame's) run a multi-hypothesis search: the object turned about
// its centre by each rotation of a uniform SO(3) set, and set to the root
// poses of its registered neighbours in time; the candidates of lowest cost
// are refined by LM, and the lowest robust cost is kept.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <random>
#include <string>
#include <vector>

#include "banmo/losses/ray_batch.h"
#include "banmo/model/model.h"
#include "banmo/optim/config.h"
#include "banmo/optim/pose_solve_report.h"
#include "banmo/optim/ray_sampler.h"

namespace banmo {

// The evaluation set-up shared by a run's frame solves.
struct FramePoseContext {
  RayBatchOptions batch;  // the stage's ray weights (the 3D cycle off) and matcher
  RayRobustLosses robust{};
  Eigen::Matrix3Xd match_grid;  // canonical points of the soft-argmax
  bool delta_skinning = false;  // as the stage's batch
  // The blocks solved: the frame's root correction and/or (config.bones)
  // its bone transforms; every other block is constant.
  bool solve_root = true;
  bool solve_bones = false;
  // The bone transforms' tangent turns each about its bone's centre
  // (StageConfig::bone_steps_about_centres).
  bool bone_steps_about_centres = false;
};

// A rotation set of `count` rotations spread uniformly over SO(3)
// (a super-Fibonacci spiral, Alexa 2022), as unit quaternions [w, x, y, z];
// the identity is not included.
std::vector<Eigen::Quaterniond> UniformRotations(int count);

// Solves frame (video, frame)'s root correction on `rays` (all of that
// frame) with LM, `config.iterations` iterations; with `search` the
// multi-hypothesis search follows whatever the local solve reached (the
// caller decides when, from the frames' costs; only when the root is
// solved). Changes only model->frame(video, frame).root_delta and (with
// context.solve_bones) its bones_t.
FramePoseSolve SolveFramePose(Model* model, int video, int frame, std::vector<Ray> rays,
                              const FramePoseContext& context, const PoseSolveConfig& config,
                              bool search);

// Every usable frame of the sampler's dataset: a local solve each, then the
// search for frames whose cost stays above config.search_ratio times the
// median (when > 0), in order of their frame index so that registered
// neighbours come first. Rays are drawn with `rng` (deterministic).
PoseSolveReport SolveAllFramePoses(Model* model, const RaySampler& sampler,
                                   const StageConfig& stage, const Eigen::AlignedBox3d& bounds,
                                   const FramePoseContext& context, std::mt19937* rng);

}  // namespace banmo
