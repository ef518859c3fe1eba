// AdamW (Loshchilov & Hutter 2019) on the minibatch's gradient, taken in
// each block's tangent space.
#include <ceres/manifold.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>

#include "banmo/optim/solver.h"
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

namespace {

// Adam's moments and step for one coordinate vector: returns the tangent
// step for gradient g at learning rate lr.
std::vector<double> AdamMove(const AdamConfig& a, const std::vector<double>& g, double lr,
                             SolverState::Moments* mo) {
  if (mo->m.empty()) {
    mo->m.assign(g.size(), 0.0);
    mo->v.assign(g.size(), 0.0);
  }
  CHECK_EQ(mo->m.size(), g.size()) << "Adam moments of another size";
  ++mo->steps;
  const double bc1 = 1.0 - std::pow(a.beta1, mo->steps);
  const double bc2 = 1.0 - std::pow(a.beta2, mo->steps);
  std::vector<double> delta(g.size());
  for (size_t k = 0; k < g.size(); ++k) {
    mo->m[k] = a.beta1 * mo->m[k] + (1.0 - a.beta1) * g[k];
    mo->v[k] = a.beta2 * mo->v[k] + (1.0 - a.beta2) * g[k] * g[k];
    delta[k] = -lr * (mo->m[k] / bc1) / (std::sqrt(mo->v[k] / bc2) + a.epsilon);
  }
  return delta;
}

// x <- x [+] delta through the block's manifold (or plain addition).
void MoveBlock(const ceres::Manifold* manifold, int size, const double* delta, double* x) {
  if (manifold == nullptr) {
    for (int k = 0; k < size; ++k) x[k] += delta[k];
    return;
  }
  std::vector<double> moved(size);
  CHECK(manifold->Plus(x, delta, moved.data()));
  std::copy(moved.begin(), moved.end(), x);
}

// One video's per-frame blocks of a group stepped in a temporal basis.
struct BasisBlocks {
  std::string moments_name;                      // "video3/bones_t_basis"
  std::vector<double*> frames;                   // every frame's block, in frame order
  std::vector<std::pair<int, size_t>> in_batch;  // (frame, offset in the gradient)
};

// The learning-rate multiplier of a group (AdamConfig's *_lr_scale).
double LrScale(const AdamConfig& a, ParameterGroup group) {
  if (group == ParameterGroup::kRoot) return a.pose_lr_scale;
  if (group == ParameterGroup::kBones || group == ParameterGroup::kBonesT) return a.bone_lr_scale;
  if (group == ParameterGroup::kLogBeta) return a.beta_lr_scale;
  if (group == ParameterGroup::kIntrinsics) return a.intrinsics_lr_scale;
  return 1.0;
}

}  // namespace

double TemporalBasisValue(int k, int t, int frames, int num_coefficients) {
  const double K = num_coefficients;
  if (k == 0) return 1.0 / std::sqrt(K);
  return std::sqrt(2.0 / K) * std::cos(M_PI * k * (t + 0.5) / frames);
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

  // Per-frame blocks whose group steps in a temporal basis: where each is.
  std::map<const double*, std::pair<BasisBlocks*, int>> basis_of;  // basis, frame
  std::map<std::pair<ParameterGroup, int>, BasisBlocks> bases;
  Model& model = sp.model();
  for (const auto& [group, K] :
       {std::pair<ParameterGroup, int>{ParameterGroup::kBonesT, a.bone_basis},
        {ParameterGroup::kRoot, a.root_basis}}) {
    if (K <= 0 || (group == ParameterGroup::kBonesT && model.num_bones() == 0)) continue;
    for (int v = 0; v < model.num_videos(); ++v) {
      BasisBlocks& basis = bases[{group, v}];
      basis.moments_name = BasisMomentsName(v, group);
      for (FrameParameters& f : model.video(v).frames) {
        double* p = group == ParameterGroup::kBonesT ? f.bones_t.data() : f.root_delta.data();
        basis_of[p] = {&basis, static_cast<int>(basis.frames.size())};
        basis.frames.push_back(p);
      }
    }
  }

  size_t offset = 0;
  for (double* p : blocks) {
    const ceres::Manifold* manifold = problem.GetManifold(p);
    const int size = problem.ParameterBlockSize(p);
    const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
    if (const auto found = basis_of.find(p); found != basis_of.end()) {
      const auto [basis, t] = found->second;
      basis->in_batch.emplace_back(t, offset);
      offset += tangent;
      continue;
    }
    const double scale = LrScale(a, sp.GroupOf(p));
    const std::vector<double> delta = AdamMove(
        a, std::vector<double>(gradient.begin() + offset, gradient.begin() + offset + tangent),
        lr * scale, &c.state->adam[c.block_names->at(p)]);
    if (sp.IsMlpWeights(p) && a.weight_decay > 0) {
      for (int k = 0; k < size; ++k) p[k] -= lr * a.weight_decay * p[k];
    }
    MoveBlock(manifold, size, delta.data(), p);
    offset += tangent;
  }
  CHECK_EQ(offset, gradient.size());

  // The temporal bases: the coefficients' gradient is the chain rule through
  // delta_t = sum_k phi_k(t) c_k (each frame's step in its own tangent
  // space), Adam runs on the coefficients, and every frame of the video
  // moves.
  for (auto& [key, basis] : bases) {
    if (basis.in_batch.empty()) continue;
    const auto [group, v] = key;
    const int frames = static_cast<int>(basis.frames.size());
    const int K = std::min(frames, group == ParameterGroup::kBonesT ? a.bone_basis : a.root_basis);
    const ceres::Manifold* manifold = problem.GetManifold(basis.frames[0]);
    const int size = problem.ParameterBlockSize(basis.frames[0]);
    const int tangent = manifold != nullptr ? manifold->TangentSize() : size;
    std::vector<double> g(static_cast<size_t>(K) * tangent, 0.0);
    for (const auto& [t, at] : basis.in_batch) {
      for (int k = 0; k < K; ++k) {
        const double phi = TemporalBasisValue(k, t, frames, K);
        for (int i = 0; i < tangent; ++i) g[k * tangent + i] += phi * gradient[at + i];
      }
    }
    const std::vector<double> coefficients =
        AdamMove(a, g, lr * LrScale(a, group), &c.state->adam[basis.moments_name]);
    std::vector<double> delta(tangent);
    for (int t = 0; t < frames; ++t) {
      std::fill(delta.begin(), delta.end(), 0.0);
      for (int k = 0; k < K; ++k) {
        const double phi = TemporalBasisValue(k, t, frames, K);
        for (int i = 0; i < tangent; ++i) delta[i] += phi * coefficients[k * tangent + i];
      }
      MoveBlock(problem.GetManifold(basis.frames[t]), size, delta.data(), basis.frames[t]);
    }
  }
  batch.Invalidate();
}

}  // namespace banmo
