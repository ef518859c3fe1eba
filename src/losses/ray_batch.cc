#include "banmo/losses/ray_batch.h"

#include <ceres/jet.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "banmo/deform/bones.h"
#include "banmo/deform/delta_skinning.h"
#include "banmo/losses/ray_functors.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "ray_pipeline.h"

namespace banmo {
const char* RayBlockName(RayBlock block) {
  static const char* kNames[kNumRayBlocks] = {"sdf",
                                              "color",
                                              "embedding",
                                              "log_beta",
                                              "appearance",
                                              "root",
                                              "bones",
                                              "bones_t",
                                              "intrinsics",
                                              "partner_root",
                                              "partner_bones_t",
                                              "delta_skinning",
                                              "rest_pose_code",
                                              "pose_code"};
  return kNames[block];
}

void RayBatchOptions::Check() const {
  if (match_top_k < 1) ThrowInputError("match_top_k: expected >= 1, got ", match_top_k);
  matcher.Check("matcher");
  if (!(skinning_jacobian_cutoff >= 0.0 && skinning_jacobian_cutoff < 1.0)) {
    ThrowInputError("skinning_jacobian_cutoff: expected a number in [0, 1), got ",
                    skinning_jacobian_cutoff);
  }
  for (int t = 0; t < kNumRayTerms; ++t) {
    const double w = weights[RayTerm(t)];
    if (!(w >= 0.0) || !std::isfinite(w)) {
      ThrowInputError("weights.", LossTermName(RayTerm(t)), ": expected a finite weight >= 0");
    }
  }
}

RayBatch::RayBatch(Model* model, const RayBatchOptions& options)
    : RayBatch(*CHECK_NOTNULL(model), options) {
  mutable_model_ = model;
}

RayBatch::RayBatch(const Model& model, const RayBatchOptions& options)
    : model_(&model), options_(options) {
  options_.Check();
  delta_skinning_ = model_->has_delta_skinning();
}

void RayBatch::SetDeltaSkinning(bool on) {
  on = on && model_->has_delta_skinning();
  CHECK(on || !model_->DeltaSkinningIsNonZero())
      << "delta skinning can only be left out while its output is zero";
  if (on != delta_skinning_) cache_valid_ = false;
  delta_skinning_ = on;
}

RayBatch::~RayBatch() = default;

void RayBatch::SetMatchGrid(const Eigen::Matrix3Xd& grid) {
  grid_ = grid;
  cache_valid_ = false;
}

void RayBatch::SetRays(std::vector<Ray> rays) {
  rays_ = std::move(rays);
  cache_valid_ = false;
  evaluations_.clear();
  bool need_match = false;
  for (const Ray& ray : rays_) {
    const bool uses = ray.HasTerm(LossTerm::kFeatureMatch, options_.weights) ||
                      ray.HasTerm(LossTerm::kCycle2d, options_.weights);
    need_match = need_match || (uses && ray.match_indices.empty());
  }
  if (need_match) {
    CHECK_GT(grid_.cols(), 0) << "SetMatchGrid must be called before rays with features";
    const CanonicalField& field = model_->field();
    EmbeddingBatch grid_batch;
    grid_batch.x = grid_;
    field.ForwardEmbeddingBatch(model_->embedding(), &grid_batch, false);
    EmbeddingMatcher matcher(options_.matcher);
    matcher.Build(grid_, grid_batch.psi);
    ParallelFor(num_rays(), [&](int begin, int end) {
      MatchResult result;
      for (int r = begin; r < end; ++r) {
        Ray& ray = rays_[r];
        const bool uses = ray.HasTerm(LossTerm::kFeatureMatch, options_.weights) ||
                          ray.HasTerm(LossTerm::kCycle2d, options_.weights);
        if (!uses || !ray.match_indices.empty()) continue;
        matcher.Match(Eigen::VectorXd(ray.feature), options_.match_top_k, &result);
        ray.match_indices = result.indices;
      }
    });
  }
  // 3D-cycle weights at the current parameters.
  std::vector<const Ray*> need_tau;
  std::vector<RayParameters> tau_params;
  std::vector<int> tau_index;
  for (int r = 0; r < num_rays(); ++r) {
    if (options_.hold_cycle_tau && rays_[r].HasTerm(LossTerm::kCycle3d, options_.weights) &&
        rays_[r].cycle_tau.empty()) {
      need_tau.push_back(&rays_[r]);
      tau_params.push_back(ModelParameters(rays_[r]));
      tau_index.push_back(r);
    }
  }
  if (!need_tau.empty()) {
    std::vector<RayEvaluation> evals;
    EvaluateRays(need_tau, tau_params, false, &evals);
    for (size_t i = 0; i < tau_index.size(); ++i) rays_[tau_index[i]].cycle_tau = evals[i].tau;
  }
}

namespace {

// The block pointers of a ray (const or mutable, from a const or mutable
// model), null for absent blocks; one code path for both.
template <class M, class Ptr>
void FillRayBlocks(M& m, const Ray& ray, bool partner, bool delta_skinning,
                   std::array<Ptr, kNumRayBlocks>* block) {
  const bool bones = m.num_bones() > 0;
  (*block)[kBlockSdf] = m.sdf();
  (*block)[kBlockColor] = m.color();
  (*block)[kBlockEmbedding] = m.embedding();
  (*block)[kBlockLogBeta] = m.log_beta();
  (*block)[kBlockAppearance] =
      m.appearance_size() > 0 ? m.video(ray.video).appearance.data() : nullptr;
  auto& f = m.frame(ray.video, ray.frame);
  (*block)[kBlockRoot] = f.root_delta.data();
  (*block)[kBlockBones] = bones ? m.bones() : nullptr;
  (*block)[kBlockBonesT] = bones ? f.bones_t.data() : nullptr;
  (*block)[kBlockIntrinsics] = m.video(ray.video).intrinsics.data();
  if (partner) {
    auto& g = m.frame(ray.video, ray.partner_frame);
    (*block)[kBlockPartnerRoot] = g.root_delta.data();
    (*block)[kBlockPartnerBonesT] = bones ? g.bones_t.data() : nullptr;
  }
  if (delta_skinning) {
    (*block)[kBlockDeltaSkin] = m.delta_skinning_params();
    (*block)[kBlockRestPoseCode] = m.rest_pose_code();
    (*block)[kBlockPoseCode] = f.pose_code.data();
  }
}

}  // namespace

RayParameters RayBatch::ModelParameters(const Ray& ray) const {
  RayParameters p;
  const bool partner = ray.HasTerm(LossTerm::kFlow, options_.weights);
  FillRayBlocks(*model_, ray, partner, delta_skinning_, &p.block);
  p.root_init = model_->frame(ray.video, ray.frame).root_init.data();
  if (partner) p.partner_root_init = model_->frame(ray.video, ray.partner_frame).root_init.data();
  return p;
}

std::vector<RayBlock> RayBatch::TermBlocks(int index, LossTerm term) const {
  CHECK(IsRayTerm(term)) << LossTermName(term) << " is not a per-ray term";
  const RayParameters p = ModelParameters(rays_[index]);
  const RayBlockMask wanted = LossInfo(term).blocks;
  std::vector<RayBlock> present;
  for (int b = 0; b < kNumRayBlocks; ++b) {
    const RayBlock block = static_cast<RayBlock>(b);
    if (Contains(wanted, block) && p.block[b] != nullptr) present.push_back(block);
  }
  return present;
}

std::vector<const double*> RayBatch::TermBlockValues(int index, LossTerm term) const {
  const RayParameters p = ModelParameters(rays_[index]);
  std::vector<const double*> out;
  for (RayBlock b : TermBlocks(index, term)) out.push_back(p.block[b]);
  return out;
}

std::vector<double*> RayBatch::TermParameterBlocks(int index, LossTerm term) const {
  CHECK(mutable_model_ != nullptr) << "a RayBatch of a const Model has no residual blocks";
  const Ray& ray = rays_[index];
  std::array<double*, kNumRayBlocks> blocks{};
  FillRayBlocks(*mutable_model_, ray, ray.HasTerm(LossTerm::kFlow, options_.weights),
                delta_skinning_, &blocks);
  std::vector<double*> out;
  for (RayBlock b : TermBlocks(index, term)) out.push_back(blocks[b]);
  return out;
}

void RayBatch::PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) {
  if (!new_evaluation_point && cache_valid_ && (cache_has_jacobians_ || !evaluate_jacobians)) {
    return;
  }
  EvaluateAll(evaluate_jacobians);
}

void RayBatch::EvaluateAll(bool jacobians) {
  std::vector<const Ray*> rays(rays_.size());
  std::vector<RayParameters> params(rays_.size());
  for (size_t r = 0; r < rays_.size(); ++r) {
    rays[r] = &rays_[r];
    params[r] = ModelParameters(rays_[r]);
  }
  EvaluateRays(rays, params, jacobians, &evaluations_);
  cache_valid_ = true;
  cache_has_jacobians_ = jacobians;
}

double RayBatch::EvaluateGradient(const RayRobustLosses& robust,
                                  std::map<const double*, Eigen::VectorXd>* gradient) {
  CHECK(gradient != nullptr);
  std::vector<const Ray*> rays(rays_.size());
  std::vector<RayParameters> params(rays_.size());
  for (size_t r = 0; r < rays_.size(); ++r) {
    rays[r] = &rays_[r];
    params[r] = ModelParameters(rays_[r]);
  }
  std::vector<RayEvaluation> evals;
  std::vector<double> ray_cost;
  std::array<Eigen::VectorXd, 4> mlp;
  EvaluateRaysImpl(rays, params, false, &robust, &evals, &ray_cost, &mlp);
  auto add = [&](const double* block, const Eigen::Ref<const Eigen::VectorXd>& g) {
    Eigen::VectorXd& sum = (*gradient)[block];
    if (sum.size() == 0) sum = Eigen::VectorXd::Zero(g.size());
    CHECK_EQ(sum.size(), g.size()) << "gradient entry of the wrong size";
    sum += g;
  };
  // Fixed order: rays in batch order, blocks in RayBlock order.
  double cost = 0.0;
  for (size_t r = 0; r < rays_.size(); ++r) {
    cost += ray_cost[r];
    for (int b = 0; b < kNumRayBlocks; ++b) {
      if (b == kBlockSdf || b == kBlockColor || b == kBlockEmbedding || b == kBlockDeltaSkin) {
        continue;
      }
      const RowMajorMatrix& row = evals[r].jacobians[b];
      if (params[r].block[b] == nullptr || row.cols() == 0) continue;
      add(params[r].block[b], row.row(0).transpose());
    }
  }
  if (!rays_.empty()) {
    add(model_->sdf(), mlp[0]);
    add(model_->color(), mlp[1]);
    if (model_->embedding_size() > 0) add(model_->embedding(), mlp[2]);
    if (delta_skinning_) add(model_->delta_skinning_params(), mlp[3]);
  }
  // The residuals serve as the value cache; the gradient rows are dropped.
  for (RayEvaluation& ev : evals) {
    for (RowMajorMatrix& j : ev.jacobians) j.resize(0, 0);
    ev.has_jacobians = false;
  }
  evaluations_ = std::move(evals);
  cache_valid_ = true;
  cache_has_jacobians_ = false;
  return cost;
}

std::array<int, kNumRayBlocks> RayBlockSizes(const Model& m, const RayParameters& p) {
  std::array<int, kNumRayBlocks> s{};
  s[kBlockSdf] = m.sdf_size();
  s[kBlockColor] = m.color_size();
  s[kBlockEmbedding] = m.embedding_size();
  s[kBlockLogBeta] = 1;
  s[kBlockAppearance] = m.appearance_size();
  s[kBlockRoot] = kPoseSize;
  s[kBlockBones] = m.bones_size();
  s[kBlockBonesT] = kPoseSize * m.num_bones();
  s[kBlockIntrinsics] = kIntrinsicsSize;
  s[kBlockPartnerRoot] = kPoseSize;
  s[kBlockPartnerBonesT] = kPoseSize * m.num_bones();
  s[kBlockDeltaSkin] = m.delta_skinning_size();
  s[kBlockRestPoseCode] = m.pose_code_size();
  s[kBlockPoseCode] = m.pose_code_size();
  for (int b = 0; b < kNumRayBlocks; ++b) {
    if (p.block[b] == nullptr) s[b] = 0;
  }
  return s;
}

void RayBatch::EvaluateRays(const std::vector<const Ray*>& rays,
                            const std::vector<RayParameters>& params, bool jacobians,
                            std::vector<RayEvaluation>* out) const {
  EvaluateRaysImpl(rays, params, jacobians, nullptr, out, nullptr, nullptr);
}

void RayBatch::EvaluateRaysImpl(const std::vector<const Ray*>& rays,
                                const std::vector<RayParameters>& params, bool full_jacobians,
                                const RayRobustLosses* robust, std::vector<RayEvaluation>* out,
                                std::vector<double>* ray_cost,
                                std::array<Eigen::VectorXd, 4>* mlp_gradient) const {
  RayPipeline pipeline(*model_, options_, grid_, rays, params, full_jacobians, robust, out,
                       ray_cost, mlp_gradient);
  pipeline.set_field_jacobians(field_jacobians_ || robust != nullptr);
  pipeline.Run();
}

}  // namespace banmo

namespace banmo {
namespace {

// One loss term of one ray. Residuals and Jacobians come from the batch's
// cache when Ceres evaluates at the point the batch prepared; otherwise the
// ray is evaluated alone with the given parameter values.
class RayTermCostFunction final : public ceres::CostFunction {
 public:
  RayTermCostFunction(RayBatch* batch, int index, LossTerm term)
      : batch_(batch),
        index_(index),
        term_(term),
        blocks_(batch->TermBlocks(index, term)),
        model_blocks_(batch->TermParameterBlocks(index, term)) {
    const Ray& ray = batch->rays()[index];
    CHECK(ray.HasTerm(term, batch->options().weights))
        << "term " << LossTermName(term) << " is not active for ray " << index;
    set_num_residuals(LossTermResiduals(term, ray.NumSamples()));
    const RayParameters p = batch->ModelParameters(ray);
    const std::array<int, kNumRayBlocks> sizes = RayBlockSizes(batch->model(), p);
    for (RayBlock b : blocks_) mutable_parameter_block_sizes()->push_back(sizes[b]);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const bool want_jacobians = jacobians != nullptr;
    bool use_cache =
        batch_->cache_valid() && (!want_jacobians || batch_->evaluation(index_).has_jacobians);
    // Ceres passes pointers into its own state vector, so the cache is
    // recognised by value: it was computed from the model's blocks, and
    // serves this call if the given values equal them (a memcmp of a few
    // kB per block, negligible next to an evaluation).
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    for (size_t i = 0; use_cache && i < blocks_.size(); ++i) {
      use_cache = parameters[i] == model_blocks_[i] ||
                  std::memcmp(parameters[i], model_blocks_[i], sizeof(double) * sizes[i]) == 0;
    }
    const RayEvaluation* ev = nullptr;
    std::vector<RayEvaluation> local;
    if (use_cache) {
      ev = &batch_->evaluation(index_);
    } else {
      const Ray& ray = batch_->rays()[index_];
      RayParameters p = batch_->ModelParameters(ray);
      for (size_t i = 0; i < blocks_.size(); ++i) p.block[blocks_[i]] = parameters[i];
      batch_->EvaluateRays({&ray}, {p}, want_jacobians, &local);
      ev = &local[0];
    }
    const int row = ev->term_row[static_cast<int>(term_)];
    CHECK_GE(row, 0);
    const int rows = num_residuals();
    std::copy(ev->residuals.begin() + row, ev->residuals.begin() + row + rows, residuals);
    if (!want_jacobians) return true;
    for (size_t i = 0; i < blocks_.size(); ++i) {
      if (jacobians[i] == nullptr) continue;
      const RowMajorMatrix& jac = ev->jacobians[blocks_[i]];
      CHECK_EQ(jac.cols(), sizes[i]) << "no Jacobian of block " << RayBlockName(blocks_[i])
                                     << ": the batch skips field Jacobians "
                                        "(SetFieldJacobians), hold the MLP blocks constant";
      Eigen::Map<RowMajorMatrix>(jacobians[i], rows, jac.cols()) = jac.middleRows(row, rows);
    }
    return true;
  }

 private:
  RayBatch* batch_;
  const int index_;
  const LossTerm term_;
  const std::vector<RayBlock> blocks_;
  const std::vector<double*> model_blocks_;
};

}  // namespace

std::unique_ptr<ceres::CostFunction> RayBatch::MakeCostFunction(int index, LossTerm term) {
  return std::make_unique<RayTermCostFunction>(this, index, term);
}

}  // namespace banmo
