#include "banmo/optim/pose_solve.h"

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>

#include "banmo/deform/bones.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/geometry/se3.h"
#include "banmo/util/logging.h"
#include "banmo/util/median.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// One frame's pose problem: the frame's rays' composite terms, every block but
// the frame's root correction and/or bone transforms constant, the batch
// without field Jacobians.
class FramePoseProblem {
 public:
  FramePoseProblem(Model* model, int video, int frame, std::vector<Ray> rays,
                   const FramePoseContext& context)
      : batch_(model, context.batch),
        root_(model->frame(video, frame).root_delta.data()),
        bones_t_(model->num_bones() > 0 ? model->frame(video, frame).bones_t.data() : nullptr) {
    batch_.SetDeltaSkinning(context.delta_skinning);
    batch_.SetFieldJacobians(false);
    batch_.SetMatchGrid(context.match_grid);
    batch_.SetRays(std::move(rays));
    ceres::Problem::Options options;
    options.evaluation_callback = &batch_;
    options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(options);
    for (int r = 0; r < batch_.num_rays(); ++r) {
      const Ray& ray = batch_.rays()[r];
      CHECK(ray.video == video && ray.frame == frame) << "a ray of another frame";
      for (LossTerm term : RayTerms()) {
        if (term == LossTerm::kCycle3d || !ray.HasTerm(term, batch_.options().weights)) continue;
        problem_->AddResidualBlock(
            batch_.MakeCostFunction(r, term).release(),
            const_cast<ceres::LossFunction*>(context.robust[static_cast<int>(term)]),
            batch_.TermParameterBlocks(r, term));
      }
    }
    if (!context.solve_root || !problem_->HasParameterBlock(root_)) root_solved_ = false;
    if (!context.solve_bones || bones_t_ == nullptr || !problem_->HasParameterBlock(bones_t_)) {
      bones_solved_ = false;
    }
    if (empty()) return;  // no residuals or nothing free: nothing to solve
    if (root_solved_) problem_->SetManifold(root_, MakePoseManifold().release());
    if (bones_solved_) {
      problem_->SetManifold(bones_t_,
                            (context.bone_steps_about_centres
                                 ? MakeStackedPivotPoseManifold(model->num_bones(), model->bones(),
                                                                kBoneSize, kBoneCenter)
                                 : MakeStackedPoseManifold(model->num_bones()))
                                .release());
    }
    std::vector<double*> blocks;
    problem_->GetParameterBlocks(&blocks);
    for (double* b : blocks) {
      const bool free = (b == root_ && root_solved_) || (b == bones_t_ && bones_solved_);
      if (!free) problem_->SetParameterBlockConstant(b);
    }
  }

  bool empty() const { return !root_solved_ && !bones_solved_; }
  bool root_solved() const { return root_solved_; }
  int num_rays() const { return batch_.num_rays(); }
  Pose root() const { return Eigen::Map<const Pose>(root_); }
  void set_root(const Pose& p) { std::copy(p.data(), p.data() + kPoseSize, root_); }

  // Cost per ray at the current root correction.
  double Cost() {
    double cost = 0.0;
    problem_->Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    return cost / std::max(1, num_rays());
  }

  // LM from the current value: iterations taken, cost per ray before and
  // after (Ceres' summary, so no extra evaluation).
  struct Result {
    int iterations = 0;
    double cost_before = 0.0;
    double cost_after = 0.0;
  };
  Result Solve(int iterations) {
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = ceres::DENSE_QR;  // 6 + 6 B unknowns at most
    so.max_num_iterations = iterations;
    so.num_threads = 1;  // the heavy work is in RayBatch, which is parallel
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    so.update_state_every_iteration = true;
    ceres::Solver::Summary summary;
    ceres::Solve(so, problem_.get(), &summary);
    const double rays = std::max(1, num_rays());
    return {static_cast<int>(summary.iterations.size()) - 1, summary.initial_cost / rays,
            summary.final_cost / rays};
  }

 private:
  RayBatch batch_;
  double* root_;
  double* bones_t_;  // null without bones
  bool root_solved_ = true;
  bool bones_solved_ = true;
  std::unique_ptr<ceres::Problem> problem_;
};

// Candidate root corrections of the search: the current one turned about
// the object's centre by each rotation of the set (G = G0 dG Q, so dG Q),
// and the root poses of the registered neighbours t +- 1, t +- 2 of the same
// video (G = G_n, so dG = G0^-1 G_n).
std::vector<Pose> SearchCandidates(const Model& model, int video, int frame, const Pose& current,
                                   int rotations) {
  std::vector<Pose> out;
  for (const Eigen::Quaterniond& q : UniformRotations(rotations)) {
    const Pose turn = PoseFromIsometry(Eigen::Isometry3d(q));
    Pose c;
    PoseCompose(current.data(), turn.data(), c.data());
    out.push_back(c);
  }
  const int frames = static_cast<int>(model.video(video).frames.size());
  const Pose& init = model.frame(video, frame).root_init;
  Pose init_inverse;
  PoseInverse(init.data(), init_inverse.data());
  for (int d : {-1, 1, -2, 2}) {
    const int n = frame + d;
    if (n < 0 || n >= frames) continue;
    const Pose g = model.RootPose(video, n);
    Pose c;
    PoseCompose(init_inverse.data(), g.data(), c.data());
    out.push_back(c);
  }
  return out;
}

}  // namespace

std::vector<Eigen::Quaterniond> UniformRotations(int count) {
  // Super-Fibonacci spiral (Alexa, CVPR 2022): point i of n on S^3.
  constexpr double kPhi = 1.4142135623730950488;  // sqrt(2)
  constexpr double kPsi = 1.533751168755204288118041;
  std::vector<Eigen::Quaterniond> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double s = i + 0.5;
    const double r = std::sqrt(s / count);
    const double R = std::sqrt(1.0 - s / count);
    const double alpha = 2.0 * M_PI * s / kPhi;
    const double beta = 2.0 * M_PI * s / kPsi;
    Eigen::Quaterniond q(R * std::cos(beta), r * std::sin(alpha), r * std::cos(alpha),
                         R * std::sin(beta));
    q.normalize();
    out.push_back(q);
  }
  return out;
}

FramePoseSolve SolveFramePose(Model* model, int video, int frame, std::vector<Ray> rays,
                              const FramePoseContext& context, const PoseSolveConfig& config,
                              bool search) {
  Timer timer;
  FramePoseSolve out;
  out.video = video;
  out.frame = frame;
  const Pose start = model->RootPose(video, frame);
  FramePoseProblem problem(model, video, frame, std::move(rays), context);
  if (problem.empty()) return out;
  const FramePoseProblem::Result local_solve = problem.Solve(config.iterations);
  out.cost_before = local_solve.cost_before;
  out.cost_after = local_solve.cost_after;
  out.iterations = local_solve.iterations;
  if (search && problem.root_solved()) {
    out.searched = true;
    const Pose local = problem.root();
    std::vector<Pose> candidates =
        SearchCandidates(*model, video, frame, local, config.search_rotations);
    out.candidates = static_cast<int>(candidates.size());
    std::vector<double> cost(candidates.size());
    for (size_t i = 0; i < candidates.size(); ++i) {
      problem.set_root(candidates[i]);
      cost[i] = problem.Cost();
    }
    std::vector<size_t> order(candidates.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return cost[a] < cost[b]; });
    Pose best = local;
    double best_cost = out.cost_after;
    const int keep = std::min<int>(config.search_keep, static_cast<int>(order.size()));
    for (int k = 0; k < keep; ++k) {
      problem.set_root(candidates[order[k]]);
      const FramePoseProblem::Result refined = problem.Solve(config.iterations);
      out.iterations += refined.iterations;
      if (refined.cost_after < best_cost) {
        best_cost = refined.cost_after;
        best = problem.root();
        out.replaced = true;
      }
    }
    problem.set_root(best);
    out.cost_after = best_cost;
  }
  const Pose end = model->RootPose(video, frame);
  out.rotation_deg = RotationAngleBetween(start.data(), end.data()) * kRadToDeg;
  out.seconds = timer.Seconds();
  return out;
}

PoseSolveReport SolveAllFramePoses(Model* model, const RaySampler& sampler,
                                   const StageConfig& stage, const Eigen::AlignedBox3d& bounds,
                                   const FramePoseContext& context, std::mt19937* rng) {
  Timer timer;
  const PoseSolveConfig& config = stage.pose_solve;
  PoseSolveReport report;
  std::vector<std::vector<Ray>> rays;
  std::vector<Pose> start;
  for (const auto& [v, t] : sampler.UsableFrames()) {
    start.push_back(model->RootPose(v, t));
    rays.push_back(sampler.SampleFrame(v, t, config.rays, stage.samples_per_ray, stage.sampling,
                                       *model, bounds, rng));
    report.frames.push_back(SolveFramePose(model, v, t, rays.back(), context, config, false));
  }
  std::vector<double> before, after;
  for (const FramePoseSolve& f : report.frames) {
    before.push_back(f.cost_before);
    after.push_back(f.cost_after);
  }
  report.median_cost_before = Median(before);
  const double median = Median(after);
  if (config.search_ratio > 0 && context.solve_root) {
    for (size_t i = 0; i < report.frames.size(); ++i) {
      FramePoseSolve& f = report.frames[i];
      if (!(f.cost_after > config.search_ratio * median)) continue;
      FramePoseSolve s = SolveFramePose(model, f.video, f.frame, rays[i], context, config, true);
      s.cost_before = f.cost_before;
      s.iterations += f.iterations;
      s.seconds += f.seconds;
      f = s;
    }
  }
  after.clear();
  for (size_t i = 0; i < report.frames.size(); ++i) {
    FramePoseSolve& f = report.frames[i];
    const Pose end = model->RootPose(f.video, f.frame);
    f.rotation_deg = RotationAngleBetween(start[i].data(), end.data()) * kRadToDeg;
    after.push_back(f.cost_after);
    report.searched += f.searched ? 1 : 0;
    report.replaced += f.replaced ? 1 : 0;
  }
  report.median_cost_after = Median(after);
  report.seconds = timer.Seconds();
  return report;
}

std::string PoseSolveReport::Describe() const {
  char line[256];
  std::snprintf(line, sizeof(line),
                "pose solve: %zu frames in %.1f s, median cost per ray %.4g -> %.4g, %d searched, "
                "%d replaced by a search candidate",
                frames.size(), seconds, median_cost_before, median_cost_after, searched, replaced);
  return line;
}

}  // namespace banmo
