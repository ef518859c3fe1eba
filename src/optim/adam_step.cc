// AdamW (Loshchilov & Hutter 2019) on the minibatch's gradient, taken in
// each block's tangent space.
#include <ceres/manifold.h>

#include <cmath>

#include "banmo/util/logging.h"
#include "step_rules.h"

namespace banmo {
namespace {

// Adds the gradient of residual block `id`'s cost, 1/2 rho(|r|^2), wrt its
// non-constant parameter blocks to (*gradient)[block] (ambient, rho' J^T r as
// ceres::Problem::Evaluate computes it). Calls the cost function directly, so
// the problem's evaluation callback (the RayBatch) is not triggered.
double AddResidualBlockGradient(const ceres::Problem& problem, ceres::ResidualBlockId id,
                                std::map<const double*, Eigen::VectorXd>* gradient) {
  const ceres::CostFunction* f = problem.GetCostFunctionForResidualBlock(id);
  const ceres::LossFunction* loss = problem.GetLossFunctionForResidualBlock(id);
  std::vector<double*> blocks;
  problem.GetParameterBlocksForResidualBlock(id, &blocks);
  const int rows = f->num_residuals();
  Eigen::VectorXd residuals(rows);
  std::vector<RowMajorMatrix> jac(blocks.size());
  std::vector<double*> jac_ptrs(blocks.size(), nullptr);
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (problem.IsParameterBlockConstant(blocks[i])) continue;
    jac[i].resize(rows, f->parameter_block_sizes()[i]);
    jac_ptrs[i] = jac[i].data();
  }
  CHECK(f->Evaluate(blocks.data(), residuals.data(), jac_ptrs.data()));
  const double sq = residuals.squaredNorm();
  double rho[3] = {sq, 1.0, 0.0};
  if (loss != nullptr) loss->Evaluate(sq, rho);
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (jac_ptrs[i] == nullptr) continue;
    Eigen::VectorXd& sum = (*gradient)[blocks[i]];
    if (sum.size() == 0) sum = Eigen::VectorXd::Zero(jac[i].cols());
    sum.noalias() += rho[1] * (jac[i].transpose() * residuals);
  }
  return 0.5 * rho[0];
}

// The gradient of the minibatch's cost in the tangent space of each block,
// in the order of `blocks`.
std::vector<double> TangentGradient(const StepContext& c, const std::vector<double*>& blocks) {
  StageProblem& sp = *c.problem;
  ceres::Problem& problem = sp.problem();
  std::vector<double> gradient;
  if (c.adam_gradient_from_ceres) {
    ceres::Problem::EvaluateOptions eo;
    eo.parameter_blocks = blocks;
    // Our cost functions only copy from the batch's cache; one thread
    // keeps Ceres' gradient sums in a fixed order (bitwise-reproducible
    // resume).
    eo.num_threads = 1;
    double cost = 0.0;
    CHECK(problem.Evaluate(eo, &cost, nullptr, &gradient, nullptr));
    return gradient;
  }
  // Ray terms without their Jacobians (one cotangent row per ray), the
  // regularisers from their cost functions; all sums in a fixed order
  // (bitwise-reproducible resume).
  std::map<const double*, Eigen::VectorXd> ambient;
  sp.batch().EvaluateGradient(sp.ray_robust(), &ambient);
  for (ceres::ResidualBlockId id : sp.regularizer_blocks()) {
    AddResidualBlockGradient(problem, id, &ambient);
  }
  for (double* p : blocks) {
    const ceres::Manifold* manifold = problem.GetManifold(p);
    const int size = problem.ParameterBlockSize(p);
    const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
    const auto found = ambient.find(p);
    if (found == ambient.end()) {  // no residual reads it
      gradient.insert(gradient.end(), tangent, 0.0);
      continue;
    }
    const Eigen::VectorXd& g = found->second;
    CHECK_EQ(g.size(), size);
    if (manifold == nullptr) {
      gradient.insert(gradient.end(), g.data(), g.data() + size);
      continue;
    }
    // g_tangent = PlusJacobian(x)^T g_ambient (chain rule through
    // x + delta at delta = 0, as Ceres does).
    RowMajorMatrix plus(size, tangent);
    CHECK(manifold->PlusJacobian(p, plus.data()));
    const Eigen::VectorXd gt = plus.transpose() * g;
    gradient.insert(gradient.end(), gt.data(), gt.data() + tangent);
  }
  return gradient;
}

}  // namespace

double LearningRate(const AdamConfig& a, int batch, int batches) {
  if (a.schedule == LrSchedule::kConstant) return a.lr;
  const double x = batches > 1 ? static_cast<double>(batch) / (batches - 1) : 1.0;
  if (x < a.warmup_fraction) {
    const double s = a.warmup_fraction > 0 ? x / a.warmup_fraction : 1.0;
    return a.lr * (0.04 + 0.96 * s);
  }
  const double s =
      a.warmup_fraction < 1 ? (x - a.warmup_fraction) / (1.0 - a.warmup_fraction) : 1.0;
  const double lo = a.lr * a.final_lr_fraction;
  return lo + 0.5 * (a.lr - lo) * (1.0 + std::cos(M_PI * s));
}

void AdamStep(const StepContext& c, const std::vector<double*>& blocks,
              const std::function<void()>& after_gradient) {
  StageProblem& sp = *c.problem;
  RayBatch& batch = sp.batch();
  if (blocks.empty()) {
    if (after_gradient) {
      batch.EvaluateAll(false);
      after_gradient();
    }
    return;
  }
  const std::vector<double> gradient = TangentGradient(c, blocks);
  if (after_gradient) {
    CHECK(batch.cache_valid());
    after_gradient();
  }
  ceres::Problem& problem = sp.problem();
  const AdamConfig& a = c.stage->adam;
  const double lr = LearningRate(a, c.batch, c.stage->batches);
  size_t offset = 0;
  for (double* p : blocks) {
    const ceres::Manifold* manifold = problem.GetManifold(p);
    const int size = problem.ParameterBlockSize(p);
    const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
    SolverState::Moments& mo = c.state->adam[c.block_names->at(p)];
    if (mo.m.empty()) {
      mo.m.assign(tangent, 0.0);
      mo.v.assign(tangent, 0.0);
    }
    ++mo.steps;
    const ParameterGroup group = sp.GroupOf(p);
    double scale = 1.0;
    if (group == ParameterGroup::kRoot) scale = a.pose_lr_scale;
    if (group == ParameterGroup::kBones || group == ParameterGroup::kBonesT) {
      scale = a.bone_lr_scale;
    }
    if (group == ParameterGroup::kLogBeta) scale = a.beta_lr_scale;
    const double bc1 = 1.0 - std::pow(a.beta1, mo.steps);
    const double bc2 = 1.0 - std::pow(a.beta2, mo.steps);
    std::vector<double> delta(tangent);
    for (int k = 0; k < tangent; ++k) {
      const double g = gradient[offset + k];
      mo.m[k] = a.beta1 * mo.m[k] + (1.0 - a.beta1) * g;
      mo.v[k] = a.beta2 * mo.v[k] + (1.0 - a.beta2) * g * g;
      delta[k] = -lr * scale * (mo.m[k] / bc1) / (std::sqrt(mo.v[k] / bc2) + a.epsilon);
    }
    if (sp.IsMlpWeights(p) && a.weight_decay > 0) {
      for (int k = 0; k < size; ++k) p[k] -= lr * a.weight_decay * p[k];
    }
    if (manifold != nullptr) {
      std::vector<double> moved(size);
      CHECK(manifold->Plus(p, delta.data(), moved.data()));
      std::copy(moved.begin(), moved.end(), p);
    } else {
      for (int k = 0; k < size; ++k) p[k] += delta[k];
    }
    offset += tangent;
  }
  CHECK_EQ(offset, gradient.size());
  batch.Invalidate();
}

}  // namespace banmo
