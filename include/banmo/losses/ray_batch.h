// Mixed-mode, batched evaluation of a minibatch of rays (docs/design.md).
//
// A RayBatch is the ceres::EvaluationCallback of a problem: before Ceres
// evaluates residual blocks at a new point, PrepareForEvaluation pushes every
// ray's samples through the MLPs in one batched pass (Eigen GEMM), runs each
// ray's templated stages (losses/ray_functors.h) with Jets over that stage's
// few local variables only, and chains the local derivatives through exact
// reverse-mode products of the MLPs (field/canonical_field.h), batched over
// the whole minibatch with one backward pass per residual row. Each
// RayTermCostFunction::Evaluate then copies its rows from that cache.
//
// Each active loss term of a ray is its own residual block: it carries only
// the parameter blocks that term depends on (the 3D cycle carries no MLP
// weights, the silhouette no colour weights), and each term gets its own
// robust loss from the stage config.
//
// For first-order steps, EvaluateGradient runs the same pipeline with one
// cotangent row per ray instead of one row per residual: with each term's
// robust loss rho, c = rho'(|r_term|^2) r_term collapses the ray's rows, the
// reverse chain carries c^T J, and each MLP gets ONE backward pass over the
// whole minibatch (a single group). The result is the gradient of
// 1/2 sum rho(|r_term|^2), what ceres::Problem::Evaluate returns, without
// forming J.
//
// When Evaluate is called at parameter values the batch did not prepare
// (e.g. ceres::GradientChecker's perturbed copies), the cost function
// evaluates its ray alone, on the fly, through the same code path: results
// are identical, only slower.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/evaluation_callback.h>
#include <ceres/loss_function.h>

#include <Eigen/Core>
#include <array>
#include <map>
#include <memory>
#include <vector>

#include "banmo/field/embedding_match.h"
#include "banmo/losses/ray.h"
#include "banmo/model/model.h"

namespace banmo {

// Robust loss of each loss term (indexed by LossTerm; nullptr = none, i.e.
// rho(s) = s), as given to ceres::Problem::AddResidualBlock.
using RayRobustLosses = std::array<const ceres::LossFunction*, kNumRayTerms>;

const char* RayBlockName(RayBlock block);

// Pointers to the values of a ray's parameter blocks (null = absent).
struct RayParameters {
  std::array<const double*, kNumRayBlocks> block{};
  const double* root_init = nullptr;          // G0^t (data)
  const double* partner_root_init = nullptr;  // G0^{t'} (data)
};

// Sizes of a ray's parameter blocks (0 for absent blocks).
std::array<int, kNumRayBlocks> RayBlockSizes(const Model& model, const RayParameters& params);

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A ray's residuals and Jacobians: composite-term rows first (LossTerm order),
// then the 3N rows of the 3D cycle.
struct RayEvaluation {
  std::vector<double> residuals;
  std::vector<double> tau;                   // rendering weights tau_i of the samples (Eq. 4)
  std::vector<double> sdf;                   // SDF at the samples (canonical, after the warp)
  std::array<int, kNumRayTerms> term_row{};  // first row of each term, -1 if inactive
  std::array<RowMajorMatrix, kNumRayBlocks> jacobians;  // rows x block size
  bool has_jacobians = false;
};

struct RayBatchOptions {
  RayLossWeights weights;           // per-term weights (0 = off)
  int match_top_k = 32;             // K of the truncated soft-argmax (Eq. 15)
  EmbeddingMatcherOptions matcher;  // temperature and search options
  // Bones whose skinning weight at a point is below this are left out of the
  // warps' derivatives there (WarpWithJacobian, deform/bones.h; residuals
  // stay exact). At 1e-4 a left-out bone moves a Jacobian entry by less than
  // 1e-4 times its own derivative terms (relative errors of 1e-3 on a test
  // scene of small bones), far below a minibatch gradient's noise, and half
  // or more of an 18-bone warp's per-bone derivative work is skipped
  // (docs/solver.md, "Skinning Jacobian cutoff"). 0 = every bone down to
  // double rounding, for exact Jacobian checks. In [0, 1).
  double skinning_jacobian_cutoff = 1e-4;
  // The rendered-embedding term (feature_render) trains the embedding MLP
  // only: its rendering weights tau_i and sample points X*_i are held at
  // their values (no derivatives into the density, log beta, root poses,
  // bones or delta skinning), so the embedding is regressed on the pixel
  // features at the surface the other terms find, and the term cannot pull
  // the shape or the motion toward the embedding it has (docs/solver.md,
  // "An embedding regressed on the features").
  bool feature_render_embedding_only = false;
  // The 3D cycle's rendering weights tau_i (Eq. 19, a constant weight) held
  // at their values at SetRays' parameters for every evaluation of the
  // minibatch (Ray::cycle_tau, one forward pass over the cycle rays in
  // SetRays): a step that evaluates at several points (Ceres' trust region)
  // needs them. false: each evaluation takes its own tau_i without their
  // derivative, the same values for a step that evaluates once, at SetRays'
  // parameters (Adam), without the extra pass (a sixth of a stage-3 batch;
  // docs/solver.md, "The 3D cycle's weights").
  bool hold_cycle_tau = true;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

class RayBatch : public ceres::EvaluationCallback {
 public:
  // A batch of a model the solver changes: its cost functions are residual
  // blocks over the model's parameter blocks.
  RayBatch(Model* model, const RayBatchOptions& options);
  // A batch that only evaluates (renders, tau): no residual blocks.
  RayBatch(const Model& model, const RayBatchOptions& options);
  ~RayBatch() override;

  const RayBatchOptions& options() const { return options_; }
  const Model& model() const { return *model_; }

  // Whether the warps add the delta-skinning logits (default: when the model
  // has delta skinning). Off is only allowed while MLP_Delta's output is
  // identically zero (Model::DeltaSkinningIsNonZero() false): then the
  // evaluation is unchanged and the delta blocks are left out of the terms
  // (the solver's schedule switches it on from a fraction of a stage).
  void SetDeltaSkinning(bool on);
  bool delta_skinning() const { return delta_skinning_; }

  // Whether Jacobian evaluations include the MLP-weight blocks (sdf, color,
  // embedding, delta_skinning; default on). Off skips their reverse passes,
  // most of an evaluation's cost, for problems that hold them constant (the
  // per-frame pose solves): a cost function asked for one of them fails.
  void SetFieldJacobians(bool on) {
    field_jacobians_ = on;
    cache_valid_ = false;
  }

  // Canonical points X of the soft-argmax (Eq. 15's V*), 3 x M.
  void SetMatchGrid(const Eigen::Matrix3Xd& grid);
  const Eigen::Matrix3Xd& match_grid() const { return grid_; }

  // Starts a new minibatch. Chooses each feature ray's top-K grid points with
  // the current embedding, and each ray's 3D-cycle weights tau_i at the
  // current parameters (both held fixed for this minibatch), unless the ray
  // already has them.
  void SetRays(std::vector<Ray> rays);
  const std::vector<Ray>& rays() const { return rays_; }
  int num_rays() const { return static_cast<int>(rays_.size()); }

  // Parameter blocks (model pointers) of `term` for ray `index`, in the order
  // the cost function expects, and their ids.
  std::vector<RayBlock> TermBlocks(int index, LossTerm term) const;
  std::vector<double*> TermParameterBlocks(int index, LossTerm term) const;
  // The same blocks read-only (also for a batch of a const Model).
  std::vector<const double*> TermBlockValues(int index, LossTerm term) const;
  RayParameters ModelParameters(const Ray& ray) const;

  // The cost function of one term of one ray (caller owns it; a
  // ceres::Problem takes ownership when added).
  std::unique_ptr<ceres::CostFunction> MakeCostFunction(int index, LossTerm term);

  // ceres::EvaluationCallback: evaluates the whole batch at the model's
  // current parameter values.
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override;

  // Evaluates every ray at the model's current values (what
  // PrepareForEvaluation does); the cache then serves the cost functions.
  void EvaluateAll(bool jacobians);
  bool cache_valid() const { return cache_valid_; }
  const RayEvaluation& evaluation(int index) const { return evaluations_[index]; }

  // The pipeline itself: evaluates `rays` with the given parameter values.
  // All rays must share the MLP blocks.
  void EvaluateRays(const std::vector<const Ray*>& rays, const std::vector<RayParameters>& params,
                    bool jacobians, std::vector<RayEvaluation>* out) const;

  // Gradient-only evaluation of the whole batch at the model's current
  // values: returns the batch's cost, sum over rays and active terms of
  // 1/2 rho_term(|r_term|^2) (Ceres' convention), and ADDS the gradient of
  // that cost wrt every parameter block the rays read to (*gradient)[block]
  // (model pointers as in ModelParameters; MLP blocks included; an absent
  // entry is created as zeros). Gradients are ambient (no manifold applied).
  // Deterministic: fixed summation order, independent of the thread count
  // except inside the MLP backward pass (fixed per thread count). The
  // residuals of this evaluation become the value cache (evaluation(r),
  // without Jacobians), so a caller needs no second forward pass for the
  // batch's losses.
  double EvaluateGradient(const RayRobustLosses& robust,
                          std::map<const double*, Eigen::VectorXd>* gradient);

  // Marks the cache stale (e.g. after parameters were changed outside Ceres).
  void Invalidate() { cache_valid_ = false; }

 private:
  struct Workspace;
  // EvaluateRays with an optional gradient mode (robust != nullptr): then
  // each evaluation's small-block "jacobians" hold one row, the ray's
  // rho'-weighted J^T r transposed, ray_cost its cost, and mlp_gradient the
  // batch's gradient wrt the sdf, color, embedding and delta-skinning blocks.
  void EvaluateRaysImpl(const std::vector<const Ray*>& rays,
                        const std::vector<RayParameters>& params, bool jacobians,
                        const RayRobustLosses* robust, std::vector<RayEvaluation>* out,
                        std::vector<double>* ray_cost,
                        std::array<Eigen::VectorXd, 4>* mlp_gradient) const;
  const Model* model_;
  Model* mutable_model_ = nullptr;  // null for a batch of a const Model
  RayBatchOptions options_;
  Eigen::Matrix3Xd grid_;
  std::vector<Ray> rays_;
  std::vector<RayEvaluation> evaluations_;
  bool cache_valid_ = false;
  bool cache_has_jacobians_ = false;
  bool delta_skinning_ = false;
  bool field_jacobians_ = true;
};

}  // namespace banmo
