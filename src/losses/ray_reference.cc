#include "banmo/losses/ray_reference.h"

#include <ceres/dynamic_autodiff_cost_function.h>

#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/losses/ray_functors.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

inline double ValueOf(double x) { return x; }
template <int N>
inline double ValueOf(const ceres::Jet<double, N>& x) {
  return x.a;
}

class RayReferenceFunctor {
 public:
  RayReferenceFunctor(const RayBatch& batch, int index, LossTerm term)
      : batch_(batch),
        ray_(batch.rays()[index]),
        term_(term),
        blocks_(batch.TermBlocks(index, term)),
        model_params_(batch.ModelParameters(ray_)) {
    sizes_ = RayBlockSizes(batch.model(), model_params_);
  }

  const std::vector<RayBlock>& blocks() const { return blocks_; }
  int BlockSize(RayBlock b) const { return sizes_[b]; }

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    const Model& model = batch_.model();
    const CanonicalField& field = model.field();
    const RayLossWeights& weights = batch_.options().weights;
    const int B = model.num_bones();
    const int n = ray_.NumSamples();

    // Every block as T: the term's parameters, or constants from the model.
    std::array<std::vector<T>, kNumRayBlocks> storage;
    std::array<const T*, kNumRayBlocks> block{};
    for (int b = 0; b < kNumRayBlocks; ++b) {
      if (model_params_.block[b] == nullptr) continue;
      storage[b].resize(sizes_[b]);
      for (int k = 0; k < sizes_[b]; ++k) storage[b][k] = T(model_params_.block[b][k]);
      block[b] = storage[b].data();
    }
    for (size_t i = 0; i < blocks_.size(); ++i) block[blocks_[i]] = parameters[i];
    const T* root = block[kBlockRoot];
    const T* intr = block[kBlockIntrinsics];
    const T* bones = block[kBlockBones];
    // Delta skinning (Eq. 14): MLP_Delta logits at the warp's input point,
    // with omega^t (backward) or omega^* (forward); null without it.
    const DeltaSkinning* delta =
        block[kBlockDeltaSkin] != nullptr ? model.delta_skinning() : nullptr;
    std::vector<T> delta_logits(delta != nullptr ? B : 0);
    auto delta_at = [&](const T* x, const T* code) -> const T* {
      if (delta == nullptr) return nullptr;
      delta->Logits(block[kBlockDeltaSkin], x, code, delta_logits.data());
      return delta_logits.data();
    };
    const T* pose_code = block[kBlockPoseCode];
    const T* rest_code = block[kBlockRestPoseCode];

    const RayCompositeFunctor composite(ray_, weights, model.options().density);
    const CompositeLocals& L = composite.locals();
    std::vector<T> u(L.size, T(0));
    std::vector<T> x_star(3 * n);
    T view[3];
    ViewDirectionInRoot(root, model_params_.root_init, intr, ray_.uv.data(), view);
    for (int i = 0; i < n; ++i) {
      T x_root[3];
      SampleInRoot(root, model_params_.root_init, intr, ray_.uv.data(), ray_.samples.depths[i],
                   x_root);
      BackwardWarp(B, bones, block[kBlockBonesT], x_root, &x_star[3 * i],
                   delta_at(x_root, pose_code));
      T sdf, rgb[3];
      field.Evaluate(block[kBlockSdf], block[kBlockColor], &x_star[3 * i], view,
                     block[kBlockAppearance], &sdf, rgb);
      u[L.sdf + i] = sdf;
      if (L.has_rgb) {
        for (int c = 0; c < 3; ++c) u[L.rgb + 3 * i + c] = rgb[c];
      }
      if (L.has_matched) {
        for (int c = 0; c < 3; ++c) u[L.canonical + 3 * i + c] = x_star[3 * i + c];
      }
      if (L.has_embedding) {
        field.EvaluateEmbedding(block[kBlockEmbedding], &x_star[3 * i],
                                &u[L.embedding + CompositeLocals::kEmbeddingDim * i]);
      }
      if (L.has_displacement) {
        T x_t2[3], uv2[2];
        ForwardWarp(B, bones, block[kBlockPartnerBonesT], &x_star[3 * i], x_t2,
                    delta_at(&x_star[3 * i], rest_code));
        ProjectRootPoint(block[kBlockPartnerRoot], model_params_.partner_root_init, intr, x_t2,
                         uv2);
        u[L.displacement + 2 * i + 0] = uv2[0] - T(ray_.uv[0]);
        u[L.displacement + 2 * i + 1] = uv2[1] - T(ray_.uv[1]);
      }
    }
    u[L.log_beta] = block[kBlockLogBeta][0];
    if (L.has_matched || L.has_cycle) {
      const int K = static_cast<int>(ray_.match_indices.size());
      std::vector<T> psi(kEmbeddingFeatureDim * K);
      std::vector<double> points(3 * K);
      for (int k = 0; k < K; ++k) {
        T x[3];
        for (int c = 0; c < 3; ++c) {
          points[3 * k + c] = batch_.match_grid()(c, ray_.match_indices[k]);
          x[c] = T(points[3 * k + c]);
        }
        field.EvaluateEmbedding(block[kBlockEmbedding], x, &psi[kEmbeddingFeatureDim * k]);
      }
      T feature[kEmbeddingFeatureDim];
      for (int c = 0; c < kEmbeddingFeatureDim; ++c) feature[c] = T(ray_.feature[c]);
      T x_hat[3];
      SoftArgmax(feature, psi.data(), points.data(), K, batch_.options().matcher.temperature,
                 x_hat);
      if (L.has_matched) {
        for (int c = 0; c < 3; ++c) u[L.matched + c] = x_hat[c];
      }
      if (L.has_cycle) {
        T x_t[3];
        ForwardWarp(B, bones, block[kBlockBonesT], x_hat, x_t, delta_at(x_hat, rest_code));
        ProjectRootPoint(root, model_params_.root_init, intr, x_t, &u[L.cycle_projection]);
      }
    }

    if (term_ == LossTerm::kFeatureRender && batch_.options().feature_render_embedding_only) {
      // The embedding only: the rendering weights' inputs (SDF values, log
      // beta) and the embedding's inputs X*_i held at their values.
      for (int i = 0; i < n; ++i) u[L.sdf + i] = T(ValueOf(u[L.sdf + i]));
      u[L.log_beta] = T(ValueOf(u[L.log_beta]));
      for (int i = 0; i < n; ++i) {
        const T x[3] = {T(ValueOf(x_star[3 * i])), T(ValueOf(x_star[3 * i + 1])),
                        T(ValueOf(x_star[3 * i + 2]))};
        field.EvaluateEmbedding(block[kBlockEmbedding], x,
                                &u[L.embedding + CompositeLocals::kEmbeddingDim * i]);
      }
    }
    if (term_ != LossTerm::kCycle3d) {
      std::vector<T> all(composite.num_residuals());
      composite(u.data(), all.data());
      int row = 0;
      for (int t = 0; t < static_cast<int>(term_); ++t) {
        if (composite.active(RayTerm(t))) {
          row += LossTermResiduals(RayTerm(t), n);
        }
      }
      for (int k = 0; k < LossTermResiduals(term_, n); ++k) residuals[k] = all[row + k];
      return true;
    }
    // 3D cycle: tau held constant (the minibatch's values when fixed, else
    // the current values without their derivative).
    std::vector<double> tau = ray_.cycle_tau;
    if (tau.empty()) {
      std::vector<T> tau_t(n);
      CompositeWeights(n, &u[L.sdf], u[L.log_beta], ray_.samples.deltas.data(),
                       model.options().density, tau_t.data());
      for (const T& v : tau_t) tau.push_back(ValueOf(v));
    }
    for (int i = 0; i < n; ++i) {
      T q[3];
      ForwardWarp(B, bones, block[kBlockBonesT], &x_star[3 * i], q,
                  delta_at(&x_star[3 * i], rest_code));
      Cycle3dResidual(Cycle3dLoss(tau[i], weights[LossTerm::kCycle3d]), root,
                      model_params_.root_init, intr, ray_.uv.data(), ray_.samples.depths[i], q,
                      residuals + 3 * i);
    }
    return true;
  }

 private:
  const RayBatch& batch_;
  const Ray ray_;
  const LossTerm term_;
  const std::vector<RayBlock> blocks_;
  const RayParameters model_params_;
  std::array<int, kNumRayBlocks> sizes_{};
};

}  // namespace

std::unique_ptr<ceres::CostFunction> MakeReferenceCostFunction(const RayBatch& batch, int index,
                                                               LossTerm term) {
  constexpr int kStride = 8;
  auto* functor = new RayReferenceFunctor(batch, index, term);
  auto cost =
      std::make_unique<ceres::DynamicAutoDiffCostFunction<RayReferenceFunctor, kStride>>(functor);
  for (RayBlock b : functor->blocks()) cost->AddParameterBlock(functor->BlockSize(b));
  cost->SetNumResiduals(LossTermResiduals(term, batch.rays()[index].NumSamples()));
  return cost;
}

}  // namespace banmo
