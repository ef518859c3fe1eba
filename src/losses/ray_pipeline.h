// The passes of RayBatch::EvaluateRays (losses/ray_batch.h) over one
// minibatch: a private class of the losses module. Each pass is a method
// over the batch's scratch (RayScratch per ray), in this order:
//   Layout                the rays' columns in the batched passes;
//   DeltaBackwardInputs   pass 0: MLP_Delta at each sample (delta skinning);
//   PlaceSamples          pass 1: sample placement, view direction, backward warp;
//   EvaluateFields        pass 2: the canonical fields, embeddings and
//                         soft-argmax for all samples at once;
//   EvaluateRay           pass 3, per ray: composite inputs, the composite functor
//                         with Jets over its locals, rendering weights, the
//                         reverse chain, the 3D cycle;
//   MlpGradient           pass 4, gradient mode: one backward pass per MLP;
//   MlpJacobians          pass 4: MLP weight Jacobians row by row;
//   DeltaCycle3dJacobians MLP_Delta Jacobians of the 3D-cycle rows.
#pragma once

#include <ceres/jet.h>

#include <Eigen/Core>
#include <array>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/deform/delta_skinning.h"
#include "banmo/field/canonical_field.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_functors.h"

namespace banmo {

using Mat37 = Eigen::Matrix<double, 3, kPoseSize>;
using Mat34 = Eigen::Matrix<double, 3, kIntrinsicsSize>;

// Jets over [x (3), root_delta (7), intrinsics (4)]: the locals of the
// projection and 3D-cycle stages.
constexpr int kPointPoseIntrinsics = 3 + kPoseSize + kIntrinsicsSize;
// Jets over [root_delta (7), intrinsics (4)]: sample placement, view direction.
constexpr int kPoseIntrinsics = kPoseSize + kIntrinsicsSize;

template <int N>
using JetN = ceres::Jet<double, N>;

template <int N>
void SeedJets(const double* values, int count, int first_direction, JetN<N>* out) {
  for (int k = 0; k < count; ++k) out[k] = JetN<N>(values[k], first_direction + k);
}

// Values and Jacobian (num_out x u.size()) of f(u), by forward-mode Jets in
// chunks of kStride directions (like ceres::DynamicAutoDiffCostFunction).
// Only the first num_seeded inputs (all when negative) get directions; the
// other columns are set to zero for the caller to fill (inputs whose
// derivatives it knows in closed form).
template <int kStride, typename Functor>
void ChunkedJacobian(const Functor& f, const std::vector<double>& u, int num_out, double* values,
                     RowMajorMatrix* jacobian, int num_seeded = -1) {
  using J = JetN<kStride>;
  const int n = static_cast<int>(u.size());
  const int seeded = num_seeded < 0 ? n : std::min(num_seeded, n);
  CHECK_GT(seeded, 0) << "ChunkedJacobian needs at least one seeded input";
  std::vector<J> uj(n), out(num_out);
  jacobian->resize(num_out, n);
  if (seeded < n) jacobian->rightCols(n - seeded).setZero();
  for (int start = 0; start < seeded; start += kStride) {
    for (int i = 0; i < n; ++i) uj[i] = J(u[i]);
    const int end = std::min(seeded, start + kStride);
    for (int i = start; i < end; ++i) uj[i].v[i - start] = 1.0;
    f(uj.data(), out.data());
    for (int r = 0; r < num_out; ++r) {
      values[r] = out[r].a;
      for (int i = start; i < end; ++i) (*jacobian)(r, i) = out[r].v[i - start];
    }
  }
}

// Projection of a root-frame point through a frame's root pose, with the
// Jacobian wrt [x (3), root_delta (7), intrinsics (4)].
inline void ProjectWithJacobian(const double* root_delta, const double* root_init,
                                const double* intrinsics, const double* x_in_root, double* uv,
                                Eigen::Matrix<double, 2, kPointPoseIntrinsics>* jacobian) {
  using J = JetN<kPointPoseIntrinsics>;
  J x[3], pose[kPoseSize], k[kIntrinsicsSize], out[2];
  SeedJets(x_in_root, 3, 0, x);
  SeedJets(root_delta, kPoseSize, 3, pose);
  SeedJets(intrinsics, kIntrinsicsSize, 3 + kPoseSize, k);
  ProjectRootPoint(pose, root_init, k, x, out);
  for (int r = 0; r < 2; ++r) {
    uv[r] = out[r].a;
    jacobian->row(r) = out[r].v.transpose();
  }
}

// Adds a (R x cols) += lhs (R x m) * rhs (m x cols) into a block of a
// Jacobian when the block exists.
template <typename Lhs, typename Rhs>
void AddProduct(RowMajorMatrix* jac, int row0, const Lhs& lhs, const Rhs& rhs) {
  if (jac->cols() == 0) return;
  jac->block(row0, 0, lhs.rows(), jac->cols()).noalias() += lhs * rhs;
}

// Per-ray intermediate values of one pipeline run.
struct RayScratch {
  int num_samples = 0;
  int field_offset = 0;  // first column of the ray's samples in the field batch
  int match_offset = 0;  // first column of the ray's K grid points in the embedding batch
  int num_match = 0;     // K (0 if the ray has no feature terms)
  // The ray's samples in the sample-embedding batch (rendered embedding):
  // those of weight tau_i >= kMinWarpTau (the only ones the rendered
  // embedding reads), in order; none without the feature_render term.
  int emb_offset = 0;
  int num_emb = 0;               // emb_samples.size()
  std::vector<int> emb_samples;  // their sample indices i
  int composite_rows = 0;
  Eigen::Matrix3Xd x_root, x_star;
  std::vector<Mat37> dxroot_droot;
  std::vector<Mat34> dxroot_dk;
  std::vector<WarpJacobian> backward;
  Eigen::Vector3d view = Eigen::Vector3d::Zero();
  Mat37 dview_droot = Mat37::Zero();
  Mat34 dview_dk = Mat34::Zero();
  Eigen::Vector3d x_hat = Eigen::Vector3d::Zero();
  RowMajorMatrix a_sdf, a_rgb, a_xhat;  // adjoints for the batched MLP backward
  RowMajorMatrix a_psi;                 // rows x 16 num_emb: of psi(X*_i), i in emb_samples
  // Delta skinning: the ray's columns in the forward-warp batch (X*_i when
  // the flow or the 3D cycle pushes them forward, then X_hat* for the 2D
  // cycle), and the adjoints of the delta logits (rows x B per column) of the
  // composite rows (a_dbw: backward warp at sample i, a_dfw: forward batch
  // column j) and of the 3D-cycle rows (3n x B each, sample i's rows 3i..).
  int fw_offset = 0;
  int fw_samples = 0;
  int fw_hat = -1;  // column of X_hat* in the forward batch, -1 = none
  RowMajorMatrix a_dbw, a_dfw, c3_dbw, c3_dfw;
};

// Row `k` of the rays' delta-logit adjoints as batch cotangents: d_bw
// (B x samples, backward warps) and d_fw (B x forward-batch columns); rays
// with fewer rows contribute zeros. *any (optional): whether any is non-zero.
void GatherDeltaAdjoints(const std::vector<RayScratch>& scratch, const std::vector<int>& fw_groups,
                         int num_bones, int k, Eigen::MatrixXd* d_bw, Eigen::MatrixXd* d_fw,
                         bool* any);

using RayJacobians = std::array<RowMajorMatrix, kNumRayBlocks>;
using ProjectionJacobian = Eigen::Matrix<double, 2, kPointPoseIntrinsics>;
using Cycle3dJacobian = Eigen::Matrix<double, 3, kPointPoseIntrinsics>;

class RayPipeline {
 public:
  RayPipeline(const Model& model, const RayBatchOptions& options, const Eigen::Matrix3Xd& grid,
              const std::vector<const Ray*>& rays, const std::vector<RayParameters>& params,
              bool full_jacobians, const RayRobustLosses* robust, std::vector<RayEvaluation>* out,
              std::vector<double>* ray_cost, std::array<Eigen::VectorXd, 4>* mlp_gradient);
  // Off: full Jacobians without the MLP-weight blocks (sdf, color,
  // embedding, delta_skinning have 0 columns), e.g. for pose-only solves.
  void set_field_jacobians(bool on) { field_jacobians = on; }
  void Run();

 private:
  // One ray's values shared by the steps of pass 3.
  struct RayWork {
    RayWork(int r, const Ray& ray, const RayParameters& p, RayScratch& s, RayEvaluation& ev,
            const RayLossWeights& weights, DensityModel density);
    const int ray_index;
    const Ray& ray;
    const RayParameters& params;
    RayScratch& scratch;
    RayEvaluation& eval;
    const int num_samples;
    const double* bones;
    const double* intr;
    const RayCompositeFunctor composite;
    const int rows;      // composite rows
    int chain_rows = 0;  // rows of the reverse chain: rows, or 1 in gradient mode
    const bool cycle3d;
    std::vector<double> locals;     // the composite functor's locals
    std::vector<char> flow_active;  // samples the flow sums (weight >= kMinWarpTau)
    std::vector<WarpJacobian> flow_warp;
    std::vector<ProjectionJacobian> flow_proj;
    WarpJacobian cycle_warp;
    ProjectionJacobian cycle_proj;
    RowMajorMatrix locals_jacobian;  // d residual / d locals (rows x |locals|)
    const std::vector<double>* tau = nullptr;
  };

  void Layout();
  void DeltaBackwardInputs();
  void PlaceSamples();
  void EvaluateFields();
  void EvaluateRay(int r);
  void InitEvaluation(RayWork& w);
  void CompositeInputs(RayWork& w);
  void CompositeResiduals(RayWork& w);
  // False when no Jacobians are wanted (the ray is done).
  bool RenderingWeights(RayWork& w);
  void ReverseComposite(RayWork& w);
  void Cycle3dSample(RayWork& w, int i, WarpJacobian* qj, Cycle3dJacobian* E) const;
  void Cycle3dGradient(RayWork& w);
  void Cycle3dRows(RayWork& w);
  void MlpGradient();
  void MlpJacobians();
  // The cotangent of the embedding MLP's outputs for residual row k of every
  // ray that has one (zero columns elsewhere): at the match candidates
  // (through the soft-argmax's backward), 16 x total_match, or at the
  // samples of the rendered embedding, 16 x total_emb.
  void MatchPsiCotangent(int k, Eigen::MatrixXd* d_psi) const;
  void SamplePsiCotangent(int k, Eigen::MatrixXd* d_psi) const;
  void DeltaCycle3dJacobians();
  // Delta logits of backward-warp sample `col` / forward-batch column `col`.
  const double* bw_logits(int col) const;
  const double* fw_logits(int col) const;
  // Chains adjoints a (rows x 3) of a warp's output through its delta
  // logits: a_dl = a dOut/dlogits (rows x B) goes to the batch column's
  // adjoint (*a_logits, rows x B), to the warp input's adjoint (*a_in,
  // rows x 3) and to the pose-code block's Jacobian rows.
  void ChainDelta(RayJacobians& jac, const Eigen::Ref<const RowMajorMatrix>& a,
                  const WarpJacobian& wj, const DeltaSkinningBatch& batch, int col,
                  RayBlock code_block, int row0, Eigen::Ref<RowMajorMatrix> a_logits,
                  Eigen::Ref<RowMajorMatrix> a_in) const;

  const Model& model;
  const CanonicalField& field;
  const RayBatchOptions& options_;
  const RayLossWeights& weights;
  const Eigen::Matrix3Xd& grid_;
  const std::vector<const Ray*>& rays;
  const std::vector<RayParameters>& params;
  const bool full_jacobians;
  const RayRobustLosses* robust;
  std::vector<RayEvaluation>* out;
  std::vector<double>* ray_cost;
  std::array<Eigen::VectorXd, 4>* mlp_gradient;
  const bool gradient;
  const bool jacobians;
  bool field_jacobians = true;
  const int num_rays;
  const int num_bones;
  const int appearance_dim;
  const double* sdf_params = nullptr;
  const double* color_params = nullptr;
  const double* embedding_params = nullptr;
  const double* delta_params = nullptr;
  const DeltaSkinning* delta = nullptr;
  int pose_code_dim = 0;
  int delta_local_dim = 0;
  std::vector<RayScratch> scratch;
  std::vector<int> field_groups, match_groups, emb_groups, fw_groups;
  int total_samples = 0;
  int total_match = 0;
  int total_emb = 0;
  int total_fw = 0;
  DeltaSkinningBatch backward_delta, forward_delta;
  FieldBatch field_batch;
  EmbeddingBatch match_batch;   // the match candidates (grid points)
  EmbeddingBatch sample_batch;  // the samples X*_i of rays with the rendered embedding
};

}  // namespace banmo
