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

namespace banmo {
namespace {

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
template <int kStride, typename Functor>
void ChunkedJacobian(const Functor& f, const std::vector<double>& u, int num_out, double* values,
                     RowMajorMatrix* jacobian) {
  using J = JetN<kStride>;
  const int n = static_cast<int>(u.size());
  std::vector<J> uj(n), out(num_out);
  jacobian->resize(num_out, n);
  for (int start = 0; start < n; start += kStride) {
    for (int i = 0; i < n; ++i) uj[i] = J(u[i]);
    const int end = std::min(n, start + kStride);
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
void ProjectWithJacobian(const double* root_delta, const double* root_init,
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

}  // namespace

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
  if (!matcher.Check()) ThrowInputError("matcher: invalid embedding matcher options");
  for (int t = 0; t < kNumRayTerms; ++t) {
    const double w = weights[RayTerm(t)];
    if (!(w >= 0.0) || !std::isfinite(w)) {
      ThrowInputError("weights.", LossTermName(RayTerm(t)), ": expected a finite weight >= 0");
    }
  }
}

// Per-ray intermediate values of one pipeline run.
struct RayScratch;
// Row `k` of the rays' delta-logit adjoints as batch cotangents: d_bw
// (B x samples, backward warps) and d_fw (B x forward-batch columns); rays
// with fewer rows contribute zeros. *any (optional): whether any is non-zero.
static void GatherDeltaAdjoints(const std::vector<RayScratch>& scratch,
                                const std::vector<int>& fw_groups, int num_bones, int k,
                                Eigen::MatrixXd* d_bw, Eigen::MatrixXd* d_fw, bool* any);

struct RayScratch {
  int num_samples = 0;
  int field_offset = 0;  // first column of the ray's samples in the field batch
  int match_offset = 0;  // first column of the ray's K grid points in the embedding batch
  int num_match = 0;     // K (0 if the ray has no feature terms)
  int render_rows = 0;
  Eigen::Matrix3Xd x_root, x_star;
  std::vector<Mat37> dxroot_droot;
  std::vector<Mat34> dxroot_dk;
  std::vector<WarpJacobian> backward;
  Eigen::Vector3d view = Eigen::Vector3d::Zero();
  Mat37 dview_droot = Mat37::Zero();
  Mat34 dview_dk = Mat34::Zero();
  Eigen::Vector3d x_hat = Eigen::Vector3d::Zero();
  RowMajorMatrix a_sdf, a_rgb, a_xhat;  // adjoints for the batched MLP backward
  // Delta skinning: the ray's columns in the forward-warp batch (X*_i when
  // the flow or the 3D cycle pushes them forward, then X_hat* for the 2D
  // cycle), and the adjoints of the delta logits (rows x B per column) of the
  // render rows (a_dbw: backward warp at sample i, a_dfw: forward batch
  // column j) and of the 3D-cycle rows (3n x B each, sample i's rows 3i..).
  int fw_offset = 0;
  int fw_samples = 0;
  int fw_hat = -1;  // column of X_hat* in the forward batch, -1 = none
  RowMajorMatrix a_dbw, a_dfw, c3_dbw, c3_dfw;
};

static void GatherDeltaAdjoints(const std::vector<RayScratch>& scratch,
                                const std::vector<int>& fw_groups, int num_bones, int k,
                                Eigen::MatrixXd* d_bw, Eigen::MatrixXd* d_fw, bool* any) {
  const int B = num_bones;
  int total_samples = 0;
  for (const RayScratch& s : scratch) total_samples += s.num_samples;
  d_bw->setZero(B, total_samples);
  d_fw->setZero(B, fw_groups.back());
  if (any != nullptr) *any = false;
  for (size_t r = 0; r < scratch.size(); ++r) {
    const RayScratch& s = scratch[r];
    if (k >= s.a_dbw.rows()) continue;
    d_bw->middleCols(s.field_offset, s.num_samples) =
        Eigen::Map<const Eigen::MatrixXd>(s.a_dbw.row(k).data(), B, s.num_samples);
    const int count = fw_groups[r + 1] - fw_groups[r];
    d_fw->middleCols(s.fw_offset, count) =
        Eigen::Map<const Eigen::MatrixXd>(s.a_dfw.row(k).data(), B, count);
    if (any != nullptr) {
      *any = *any || s.a_dbw.row(k).squaredNorm() > 0 || s.a_dfw.row(k).squaredNorm() > 0;
    }
  }
}

RayBatch::RayBatch(Model* model, const RayBatchOptions& options)
    : model_(model), options_(options) {
  CHECK(model_ != nullptr);
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
    if (rays_[r].HasTerm(LossTerm::kCycle3d, options_.weights) && rays_[r].cycle_tau.empty()) {
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

RayParameters RayBatch::ModelParameters(const Ray& ray) const {
  RayParameters p;
  Model& m = *model_;
  const bool bones = m.num_bones() > 0;
  p.block[kBlockSdf] = m.sdf();
  p.block[kBlockColor] = m.color();
  p.block[kBlockEmbedding] = m.embedding();
  p.block[kBlockLogBeta] = m.log_beta();
  p.block[kBlockAppearance] =
      m.appearance_size() > 0 ? m.video(ray.video).appearance.data() : nullptr;
  const FrameParameters& f = m.frame(ray.video, ray.frame);
  p.block[kBlockRoot] = f.root_delta.data();
  p.root_init = f.root_init.data();
  p.block[kBlockBones] = bones ? m.bones() : nullptr;
  p.block[kBlockBonesT] = bones ? f.bones_t.data() : nullptr;
  p.block[kBlockIntrinsics] = m.video(ray.video).intrinsics.data();
  if (ray.HasTerm(LossTerm::kFlow, options_.weights)) {
    const FrameParameters& g = m.frame(ray.video, ray.partner_frame);
    p.block[kBlockPartnerRoot] = g.root_delta.data();
    p.partner_root_init = g.root_init.data();
    p.block[kBlockPartnerBonesT] = bones ? g.bones_t.data() : nullptr;
  }
  if (delta_skinning_) {
    p.block[kBlockDeltaSkin] = m.delta_skinning_params();
    p.block[kBlockRestPoseCode] = m.rest_pose_code();
    p.block[kBlockPoseCode] = f.pose_code.data();
  }
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

std::vector<double*> RayBatch::TermParameterBlocks(int index, LossTerm term) const {
  const RayParameters p = ModelParameters(rays_[index]);
  std::vector<double*> out;
  for (RayBlock b : TermBlocks(index, term)) out.push_back(const_cast<double*>(p.block[b]));
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
  CHECK_EQ(rays.size(), params.size());
  // Gradient mode: one cotangent row per ray (c^T J) instead of full Jacobians.
  const bool gradient = robust != nullptr;
  CHECK(!(gradient && full_jacobians));
  CHECK(!gradient || (ray_cost != nullptr && mlp_gradient != nullptr));
  // Local derivatives (Jets, warp and projection Jacobians) are needed in both.
  const bool jacobians = full_jacobians || gradient;
  const int num_rays = static_cast<int>(rays.size());
  out->assign(num_rays, RayEvaluation());
  if (gradient) {
    ray_cost->assign(num_rays, 0.0);
    for (auto& g : *mlp_gradient) g.resize(0);
  }
  if (num_rays == 0) return;
  const Model& model = *model_;
  const CanonicalField& field = model.field();
  const RayLossWeights& weights = options_.weights;
  const int B = model.num_bones();
  const int A = model.appearance_size();
  const double* sdf_params = params[0].block[kBlockSdf];
  const double* color_params = params[0].block[kBlockColor];
  const double* embedding_params = params[0].block[kBlockEmbedding];
  const double* delta_params = params[0].block[kBlockDeltaSkin];
  for (const RayParameters& p : params) {
    CHECK(p.block[kBlockSdf] == sdf_params && p.block[kBlockColor] == color_params &&
          p.block[kBlockEmbedding] == embedding_params && p.block[kBlockDeltaSkin] == delta_params)
        << "rays of one EvaluateRays call must share the MLP blocks";
  }
  // Delta skinning (Eq. 14): logits of MLP_Delta added in every warp.
  const DeltaSkinning* delta = delta_params != nullptr ? model.delta_skinning() : nullptr;
  const int P = delta != nullptr ? delta->CodeDim() : 0;
  const int DL = delta != nullptr ? delta->LocalDim() : 0;

  // Layout of the batched field and embedding passes.
  std::vector<RayScratch> scratch(num_rays);
  std::vector<int> field_groups(num_rays + 1, 0), match_groups(num_rays + 1, 0);
  std::vector<int> fw_groups(num_rays + 1, 0);
  for (int r = 0; r < num_rays; ++r) {
    const Ray& ray = *rays[r];
    RayScratch& s = scratch[r];
    s.num_samples = ray.NumSamples();
    s.field_offset = field_groups[r];
    field_groups[r + 1] = field_groups[r] + s.num_samples;
    const bool match =
        ray.HasTerm(LossTerm::kFeatureMatch, weights) || ray.HasTerm(LossTerm::kCycle2d, weights);
    if (match) {
      CHECK(!ray.match_indices.empty()) << "feature ray without match indices (call SetRays)";
      CHECK_GT(grid_.cols(), 0);
    }
    s.num_match = match ? static_cast<int>(ray.match_indices.size()) : 0;
    s.match_offset = match_groups[r];
    match_groups[r + 1] = match_groups[r] + s.num_match;
    s.fw_offset = fw_groups[r];
    int fw_count = 0;
    if (delta != nullptr) {
      const bool push_samples =
          ray.HasTerm(LossTerm::kFlow, weights) || ray.HasTerm(LossTerm::kCycle3d, weights);
      s.fw_samples = push_samples ? s.num_samples : 0;
      fw_count = s.fw_samples;
      if (ray.HasTerm(LossTerm::kCycle2d, weights)) s.fw_hat = s.fw_offset + fw_count++;
    }
    fw_groups[r + 1] = fw_groups[r] + fw_count;
  }
  const int total_samples = field_groups[num_rays];
  const int total_match = match_groups[num_rays];
  const int total_fw = fw_groups[num_rays];

  // Pass 0 (delta skinning only, batched): MLP_Delta at every sample's
  // time-t point with the frame's pose code, for the backward warps.
  DeltaSkinningBatch bw, fw;
  if (delta != nullptr) {
    bw.x.resize(3, total_samples);
    bw.codes.resize(P, total_samples);
    ParallelFor(num_rays, [&](int begin, int end) {
      for (int r = begin; r < end; ++r) {
        const Ray& ray = *rays[r];
        const RayParameters& p = params[r];
        const RayScratch& s = scratch[r];
        for (int i = 0; i < s.num_samples; ++i) {
          SampleInRoot(p.block[kBlockRoot], p.root_init, p.block[kBlockIntrinsics], ray.uv.data(),
                       ray.samples.depths[i], bw.x.col(s.field_offset + i).data());
        }
        bw.codes.middleCols(s.field_offset, s.num_samples) =
            Eigen::Map<const Eigen::VectorXd>(p.block[kBlockPoseCode], P)
                .replicate(1, s.num_samples);
      }
    });
    delta->ForwardBatch(delta_params, &bw, jacobians);
  }
  // Delta logits of backward-warp sample `col` / forward-batch column `col`.
  auto bw_logits = [&](int col) -> const double* {
    return delta != nullptr ? bw.logits.col(col).data() : nullptr;
  };
  auto fw_logits = [&](int col) -> const double* {
    return delta != nullptr ? fw.logits.col(col).data() : nullptr;
  };

  FieldBatch fb;
  fb.x.resize(3, total_samples);
  fb.view_dir.resize(3, total_samples);
  fb.appearance.resize(A, total_samples);

  // Pass 1 (per ray): sample placement, view direction, backward warp.
  ParallelFor(num_rays, [&](int begin, int end) {
    for (int r = begin; r < end; ++r) {
      const Ray& ray = *rays[r];
      const RayParameters& p = params[r];
      RayScratch& s = scratch[r];
      const int n = s.num_samples;
      const double* root = p.block[kBlockRoot];
      const double* intr = p.block[kBlockIntrinsics];
      s.x_root.resize(3, n);
      s.x_star.resize(3, n);
      if (jacobians) {
        s.dxroot_droot.resize(n);
        s.dxroot_dk.resize(n);
        s.backward.resize(n);
      }
      for (int i = 0; i < n; ++i) {
        const double depth = ray.samples.depths[i];
        if (jacobians) {
          using J = JetN<kPoseIntrinsics>;
          J pose[kPoseSize], k[kIntrinsicsSize], x[3];
          SeedJets(root, kPoseSize, 0, pose);
          SeedJets(intr, kIntrinsicsSize, kPoseSize, k);
          SampleInRoot(pose, p.root_init, k, ray.uv.data(), depth, x);
          for (int c = 0; c < 3; ++c) {
            s.x_root(c, i) = x[c].a;
            s.dxroot_droot[i].row(c) = x[c].v.head<kPoseSize>().transpose();
            s.dxroot_dk[i].row(c) = x[c].v.tail<kIntrinsicsSize>().transpose();
          }
          WarpWithJacobian(WarpDirection::kBackward, B, p.block[kBlockBones], p.block[kBlockBonesT],
                           s.x_root.col(i).data(), s.x_star.col(i).data(), &s.backward[i],
                           bw_logits(s.field_offset + i));
        } else {
          SampleInRoot(root, p.root_init, intr, ray.uv.data(), depth, s.x_root.col(i).data());
          BackwardWarp(B, p.block[kBlockBones], p.block[kBlockBonesT], s.x_root.col(i).data(),
                       s.x_star.col(i).data(), bw_logits(s.field_offset + i));
        }
      }
      if (jacobians) {
        using J = JetN<kPoseIntrinsics>;
        J pose[kPoseSize], k[kIntrinsicsSize], v[3];
        SeedJets(root, kPoseSize, 0, pose);
        SeedJets(intr, kIntrinsicsSize, kPoseSize, k);
        ViewDirectionInRoot(pose, p.root_init, k, ray.uv.data(), v);
        for (int c = 0; c < 3; ++c) {
          s.view[c] = v[c].a;
          s.dview_droot.row(c) = v[c].v.head<kPoseSize>().transpose();
          s.dview_dk.row(c) = v[c].v.tail<kIntrinsicsSize>().transpose();
        }
      } else {
        ViewDirectionInRoot(root, p.root_init, intr, ray.uv.data(), s.view.data());
      }
      fb.x.middleCols(s.field_offset, n) = s.x_star;
      fb.view_dir.middleCols(s.field_offset, n) = s.view.replicate(1, n);
      if (A > 0) {
        const Eigen::Map<const Eigen::VectorXd> code(p.block[kBlockAppearance], A);
        fb.appearance.middleCols(s.field_offset, n) = code.replicate(1, n);
      }
    }
  });

  // Pass 2 (batched): canonical fields at all samples; embeddings at the
  // rays' match candidates and the soft-argmax X_hat* (Eq. 15).
  field.ForwardBatch(sdf_params, color_params, &fb, jacobians);
  EmbeddingBatch eb;
  if (total_match > 0) {
    eb.x.resize(3, total_match);
    for (int r = 0; r < num_rays; ++r) {
      const Ray& ray = *rays[r];
      for (int k = 0; k < scratch[r].num_match; ++k) {
        eb.x.col(scratch[r].match_offset + k) = grid_.col(ray.match_indices[k]);
      }
    }
    field.ForwardEmbeddingBatch(embedding_params, &eb, false);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      if (s.num_match == 0) continue;
      const Eigen::MatrixXd psi = eb.psi.middleCols(s.match_offset, s.num_match);
      const Eigen::Matrix3Xd points = eb.x.middleCols(s.match_offset, s.num_match);
      SoftArgmax(rays[r]->feature.data(), psi.data(), points.data(), s.num_match,
                 options_.matcher.temperature, scratch[r].x_hat.data());
    }
  }
  // Delta skinning, forward warps: MLP_Delta at the canonical points pushed
  // forward (X*_i, X_hat*) with the rest-pose code.
  if (delta != nullptr && total_fw > 0) {
    fw.x.resize(3, total_fw);
    fw.codes.resize(P, total_fw);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      const Eigen::Map<const Eigen::VectorXd> rest_code(params[r].block[kBlockRestPoseCode], P);
      fw.x.middleCols(s.fw_offset, s.fw_samples) = s.x_star.leftCols(s.fw_samples);
      if (s.fw_hat >= 0) fw.x.col(s.fw_hat) = s.x_hat;
      const int count = fw_groups[r + 1] - fw_groups[r];
      fw.codes.middleCols(s.fw_offset, count) = rest_code.replicate(1, count);
    }
    delta->ForwardBatch(delta_params, &fw, jacobians);
  }

  // Pass 3 (per ray): forward warps, projections, the render functor with
  // Jets over its locals, the 3D cycle, and the reverse chain to the small
  // parameter blocks.
  ParallelFor(num_rays, [&](int begin, int end) {
    for (int r = begin; r < end; ++r) {
      const Ray& ray = *rays[r];
      const RayParameters& p = params[r];
      RayScratch& s = scratch[r];
      RayEvaluation& ev = (*out)[r];
      const int n = s.num_samples;
      const double* bones = p.block[kBlockBones];
      const double* intr = p.block[kBlockIntrinsics];
      const RayRenderFunctor render(ray, weights);
      const RenderLocals& L = render.locals();
      const int R = render.num_residuals();
      // Rows of the reverse chain: R, or one cotangent row in gradient mode.
      const int Rc = gradient ? std::min(R, 1) : R;
      s.render_rows = Rc;
      const bool cycle3d = ray.HasTerm(LossTerm::kCycle3d, weights);
      const int total_rows = R + (cycle3d ? 3 * n : 0);
      ev.residuals.assign(total_rows, 0.0);
      ev.term_row.fill(-1);
      {
        int row = 0;
        for (int t = 0; t < kNumRenderTerms; ++t) {
          if (render.active(RayTerm(t))) {
            ev.term_row[t] = row;
            row += LossTermResiduals(RayTerm(t), n);
          }
        }
        if (cycle3d) ev.term_row[static_cast<int>(LossTerm::kCycle3d)] = R;
      }
      const std::array<int, kNumRayBlocks> sizes = RayBlockSizes(model, p);
      if (jacobians) {
        ev.has_jacobians = !gradient;
        for (int b = 0; b < kNumRayBlocks; ++b) {
          const bool mlp = b == kBlockSdf || b == kBlockColor || b == kBlockEmbedding;
          ev.jacobians[b].setZero(mlp ? Rc : (gradient ? 1 : total_rows), sizes[b]);
        }
      }

      // Locals of the render functor.
      std::vector<double> u(L.size, 0.0);
      for (int i = 0; i < n; ++i) {
        const int col = s.field_offset + i;
        u[L.sdf + i] = fb.sdf(col);
        if (L.has_rgb) {
          for (int c = 0; c < 3; ++c) u[L.rgb + 3 * i + c] = fb.rgb(c, col);
        }
        if (L.has_matched) {
          for (int c = 0; c < 3; ++c) u[L.canonical + 3 * i + c] = s.x_star(c, i);
        }
      }
      u[L.log_beta] = *p.block[kBlockLogBeta];
      // Flow: each X*_i pushed with the forward warp of t' and projected (Eq. 6).
      std::vector<WarpJacobian> flow_warp(L.has_displacement && jacobians ? n : 0);
      std::vector<Eigen::Matrix<double, 2, kPointPoseIntrinsics>> flow_proj(flow_warp.size());
      if (L.has_displacement) {
        for (int i = 0; i < n; ++i) {
          Eigen::Vector3d x_t2;
          Eigen::Vector2d uv2;
          if (jacobians) {
            WarpWithJacobian(WarpDirection::kForward, B, bones, p.block[kBlockPartnerBonesT],
                             s.x_star.col(i).data(), x_t2.data(), &flow_warp[i],
                             fw_logits(s.fw_offset + i));
            ProjectWithJacobian(p.block[kBlockPartnerRoot], p.partner_root_init, intr, x_t2.data(),
                                uv2.data(), &flow_proj[i]);
          } else {
            ForwardWarp(B, bones, p.block[kBlockPartnerBonesT], s.x_star.col(i).data(), x_t2.data(),
                        fw_logits(s.fw_offset + i));
            ProjectRootPoint(p.block[kBlockPartnerRoot], p.partner_root_init, intr, x_t2.data(),
                             uv2.data());
          }
          u[L.displacement + 2 * i + 0] = uv2[0] - ray.uv[0];
          u[L.displacement + 2 * i + 1] = uv2[1] - ray.uv[1];
        }
      }
      if (L.has_matched) {
        for (int c = 0; c < 3; ++c) u[L.matched + c] = s.x_hat[c];
      }
      // 2D cycle: X_hat* pushed forward to t and projected (Eq. 18).
      WarpJacobian cycle_warp;
      Eigen::Matrix<double, 2, kPointPoseIntrinsics> cycle_proj;
      if (L.has_cycle) {
        Eigen::Vector3d x_t;
        Eigen::Vector2d uv_c;
        if (jacobians) {
          WarpWithJacobian(WarpDirection::kForward, B, bones, p.block[kBlockBonesT], s.x_hat.data(),
                           x_t.data(), &cycle_warp, fw_logits(s.fw_hat));
          ProjectWithJacobian(p.block[kBlockRoot], p.root_init, intr, x_t.data(), uv_c.data(),
                              &cycle_proj);
        } else {
          ForwardWarp(B, bones, p.block[kBlockBonesT], s.x_hat.data(), x_t.data(),
                      fw_logits(s.fw_hat));
          ProjectRootPoint(p.block[kBlockRoot], p.root_init, intr, x_t.data(), uv_c.data());
        }
        u[L.cycle_projection + 0] = uv_c[0];
        u[L.cycle_projection + 1] = uv_c[1];
      }

      RowMajorMatrix D;  // d residual / d u  (R x |u|)
      if (R > 0) {
        if (jacobians) {
          ChunkedJacobian<32>(render, u, R, ev.residuals.data(), &D);
        } else {
          render(u.data(), ev.residuals.data());
        }
      }
      if (gradient && R > 0) {
        // Each render term's rows collapse into c = rho'(s) r, s = |r_term|^2.
        Eigen::RowVectorXd c(R);
        for (int t = 0; t < kNumRenderTerms; ++t) {
          const int row = ev.term_row[t];
          if (row < 0) continue;
          const int rows = LossTermResiduals(RayTerm(t), n);
          const Eigen::Map<const Eigen::RowVectorXd> r_t(ev.residuals.data() + row, rows);
          const double sq = r_t.squaredNorm();
          double rho[3] = {sq, 1.0, 0.0};
          if ((*robust)[t] != nullptr) (*robust)[t]->Evaluate(sq, rho);
          (*ray_cost)[r] += 0.5 * rho[0];
          c.segment(row, rows) = rho[1] * r_t;
        }
        D = (c * D).eval();
      }

      // Rendering weights; the 3D cycle (Eq. 19) uses the ray's fixed
      // cycle_tau when set (the minibatch's constants), else these values.
      {
        std::vector<double> sdf(n);
        for (int i = 0; i < n; ++i) sdf[i] = fb.sdf(s.field_offset + i);
        ev.tau.resize(n);
        CompositeWeights(n, sdf.data(), *p.block[kBlockLogBeta], ray.samples.deltas.data(),
                         ev.tau.data());
      }
      const std::vector<double>& tau = ray.cycle_tau.empty() ? ev.tau : ray.cycle_tau;
      CHECK_EQ(static_cast<int>(tau.size()), n);

      if (!jacobians) {
        if (cycle3d) {
          for (int i = 0; i < n; ++i) {
            Eigen::Vector3d q;
            ForwardWarp(B, bones, p.block[kBlockBonesT], s.x_star.col(i).data(), q.data(),
                        fw_logits(s.fw_offset + i));
            Cycle3dResidual(Cycle3dLoss(tau[i], weights[LossTerm::kCycle3d]), p.block[kBlockRoot],
                            p.root_init, intr, ray.uv.data(), ray.samples.depths[i], q.data(),
                            ev.residuals.data() + R + 3 * i);
          }
        }
        continue;
      }

      // ---- Reverse chain (render rows). ----
      auto& jac = ev.jacobians;
      RowMajorMatrix a_xstar = RowMajorMatrix::Zero(Rc, 3 * n);
      Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> a_view =
          Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>::Zero(Rc, 3);
      s.a_sdf = RowMajorMatrix::Zero(Rc, n);
      s.a_rgb = RowMajorMatrix::Zero(Rc, 3 * n);
      s.a_xhat = RowMajorMatrix::Zero(Rc, 3);
      if (delta != nullptr) {
        // Gradient mode: one cotangent row shared by the render and 3D-cycle terms.
        const int rows = gradient ? 1 : Rc;
        s.a_dbw = RowMajorMatrix::Zero(rows, B * n);
        s.a_dfw = RowMajorMatrix::Zero(rows, B * (fw_groups[r + 1] - fw_groups[r]));
        if (cycle3d && !gradient) {
          s.c3_dbw = RowMajorMatrix::Zero(3 * n, B);
          s.c3_dfw = RowMajorMatrix::Zero(3 * n, B);
        }
      }
      // Chains adjoints a (rows x 3) of a warp's output through its delta
      // logits: a_dl = a dOut/dlogits (rows x B) goes to the batch column's
      // adjoint (*a_logits, rows x B), to the warp input's adjoint (*a_in,
      // rows x 3) and to the pose-code block's Jacobian rows.
      auto chain_delta = [&](const Eigen::Ref<const RowMajorMatrix>& a, const WarpJacobian& wj,
                             const DeltaSkinningBatch& batch, int col, RayBlock code_block,
                             int row0, Eigen::Ref<RowMajorMatrix> a_logits,
                             Eigen::Ref<RowMajorMatrix> a_in) {
        const RowMajorMatrix a_dl = a * wj.d_delta_logits;
        const auto jd = batch.jacobian.middleCols(static_cast<Eigen::Index>(DL) * col, DL);
        a_in.noalias() += a_dl * jd.leftCols<3>();
        AddProduct(&jac[code_block], row0, a_dl, jd.rightCols(P));
        a_logits += a_dl;
      };
      if (Rc > 0) {
        s.a_sdf = D.middleCols(L.sdf, n);
        if (L.has_rgb) s.a_rgb = D.middleCols(L.rgb, 3 * n);
        if (L.has_matched) {
          a_xstar += D.middleCols(L.canonical, 3 * n);
          s.a_xhat += D.middleCols(L.matched, 3);
        }
        jac[kBlockLogBeta].topRows(Rc).col(0) += D.col(L.log_beta);
      }
      // Field inputs: X*_i, view direction, appearance code.
      for (int i = 0; i < n && Rc > 0; ++i) {
        const int col = s.field_offset + i;
        a_xstar.middleCols<3>(3 * i).noalias() += s.a_sdf.col(i) * fb.dsdf_dx.col(col).transpose();
        if (L.has_rgb) {
          const auto a_rgb_i = s.a_rgb.middleCols<3>(3 * i);
          a_xstar.middleCols<3>(3 * i).noalias() += a_rgb_i * fb.drgb_dx.middleCols<3>(3 * col);
          if (field.options().use_view_direction) {
            a_view.noalias() += a_rgb_i * fb.drgb_dview.middleCols<3>(3 * col);
          }
          if (A > 0) {
            AddProduct(&jac[kBlockAppearance], 0, a_rgb_i,
                       fb.drgb_dappearance.middleCols(A * col, A));
          }
        }
      }
      // Flow: displacement_i = Pi_{t'}(G^{t'} W^{t',->}(X*_i)) - x.
      if (L.has_displacement) {
        for (int i = 0; i < n; ++i) {
          const auto a_disp = D.middleCols<2>(L.displacement + 2 * i);
          const Eigen::Matrix<double, Eigen::Dynamic, 3> a_p = a_disp * flow_proj[i].leftCols<3>();
          AddProduct(&jac[kBlockPartnerRoot], 0, a_disp, flow_proj[i].middleCols<kPoseSize>(3));
          AddProduct(&jac[kBlockIntrinsics], 0, a_disp, flow_proj[i].rightCols<kIntrinsicsSize>());
          a_xstar.middleCols<3>(3 * i).noalias() += a_p * flow_warp[i].d_x;
          AddProduct(&jac[kBlockBones], 0, a_p, flow_warp[i].d_bones);
          AddProduct(&jac[kBlockPartnerBonesT], 0, a_p, flow_warp[i].d_bones_t);
          if (delta != nullptr) {
            chain_delta(a_p, flow_warp[i], fw, s.fw_offset + i, kBlockRestPoseCode, 0,
                        s.a_dfw.block(0, B * i, a_p.rows(), B), a_xstar.middleCols<3>(3 * i));
          }
        }
      }
      // 2D cycle: Pi_t(G^t W^{t,->}(X_hat*)).
      if (L.has_cycle) {
        const auto a_c = D.middleCols<2>(L.cycle_projection);
        const Eigen::Matrix<double, Eigen::Dynamic, 3> a_p = a_c * cycle_proj.leftCols<3>();
        AddProduct(&jac[kBlockRoot], 0, a_c, cycle_proj.middleCols<kPoseSize>(3));
        AddProduct(&jac[kBlockIntrinsics], 0, a_c, cycle_proj.rightCols<kIntrinsicsSize>());
        s.a_xhat.noalias() += a_p * cycle_warp.d_x;
        AddProduct(&jac[kBlockBones], 0, a_p, cycle_warp.d_bones);
        AddProduct(&jac[kBlockBonesT], 0, a_p, cycle_warp.d_bones_t);
        if (delta != nullptr) {
          chain_delta(a_p, cycle_warp, fw, s.fw_hat, kBlockRestPoseCode, 0,
                      s.a_dfw.block(0, B * (s.fw_hat - s.fw_offset), a_p.rows(), B), s.a_xhat);
        }
      }
      // Backward warp and sample placement of every X*_i.
      for (int i = 0; i < n && Rc > 0; ++i) {
        const auto a_x = a_xstar.middleCols<3>(3 * i);
        RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
        if (delta != nullptr) {
          chain_delta(a_x, s.backward[i], bw, s.field_offset + i, kBlockPoseCode, 0,
                      s.a_dbw.block(0, B * i, Rc, B), a_root_pt);
        }
        AddProduct(&jac[kBlockBones], 0, a_x, s.backward[i].d_bones);
        AddProduct(&jac[kBlockBonesT], 0, a_x, s.backward[i].d_bones_t);
        AddProduct(&jac[kBlockRoot], 0, a_root_pt, s.dxroot_droot[i]);
        AddProduct(&jac[kBlockIntrinsics], 0, a_root_pt, s.dxroot_dk[i]);
      }
      if (Rc > 0) {
        AddProduct(&jac[kBlockRoot], 0, a_view, s.dview_droot);
        AddProduct(&jac[kBlockIntrinsics], 0, a_view, s.dview_dk);
      }

      // ---- 3D cycle, gradient mode: all residuals first (rho' needs the
      // whole term's |r|^2), then one cotangent row c_i^T E_i per sample. ----
      if (cycle3d && gradient) {
        using J = JetN<kPointPoseIntrinsics>;
        std::vector<WarpJacobian> qjs(n);
        std::vector<Eigen::Matrix<double, 3, kPointPoseIntrinsics>> Es(n);
        for (int i = 0; i < n; ++i) {
          Eigen::Vector3d q;
          WarpWithJacobian(WarpDirection::kForward, B, bones, p.block[kBlockBonesT],
                           s.x_star.col(i).data(), q.data(), &qjs[i], fw_logits(s.fw_offset + i));
          J qj_jet[3], pose[kPoseSize], k[kIntrinsicsSize], res[3];
          SeedJets(q.data(), 3, 0, qj_jet);
          SeedJets(p.block[kBlockRoot], kPoseSize, 3, pose);
          SeedJets(intr, kIntrinsicsSize, 3 + kPoseSize, k);
          Cycle3dResidual(Cycle3dLoss(tau[i], weights[LossTerm::kCycle3d]), pose, p.root_init, k,
                          ray.uv.data(), ray.samples.depths[i], qj_jet, res);
          for (int c = 0; c < 3; ++c) {
            ev.residuals[R + 3 * i + c] = res[c].a;
            Es[i].row(c) = res[c].v.transpose();
          }
        }
        const Eigen::Map<const Eigen::VectorXd> r_t(ev.residuals.data() + R, 3 * n);
        const double sq = r_t.squaredNorm();
        double rho[3] = {sq, 1.0, 0.0};
        const int t = static_cast<int>(LossTerm::kCycle3d);
        if ((*robust)[t] != nullptr) (*robust)[t]->Evaluate(sq, rho);
        (*ray_cost)[r] += 0.5 * rho[0];
        for (int i = 0; i < n; ++i) {
          const Eigen::Matrix<double, 1, kPointPoseIntrinsics> e =
              rho[1] * r_t.segment<3>(3 * i).transpose() * Es[i];
          const Eigen::Matrix<double, 1, 3> a_q = e.leftCols<3>();
          AddProduct(&jac[kBlockRoot], 0, e.middleCols<kPoseSize>(3),
                     Eigen::Matrix<double, kPoseSize, kPoseSize>::Identity());
          AddProduct(&jac[kBlockIntrinsics], 0, e.rightCols<kIntrinsicsSize>(),
                     Eigen::Matrix<double, kIntrinsicsSize, kIntrinsicsSize>::Identity());
          RowMajorMatrix a_x = a_q * qjs[i].d_x;
          AddProduct(&jac[kBlockBones], 0, a_q, qjs[i].d_bones);
          AddProduct(&jac[kBlockBonesT], 0, a_q, qjs[i].d_bones_t);
          if (delta != nullptr) {
            chain_delta(a_q, qjs[i], fw, s.fw_offset + i, kBlockRestPoseCode, 0,
                        s.a_dfw.block(0, B * i, 1, B), a_x);
          }
          RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
          if (delta != nullptr) {
            chain_delta(a_x, s.backward[i], bw, s.field_offset + i, kBlockPoseCode, 0,
                        s.a_dbw.block(0, B * i, 1, B), a_root_pt);
          }
          AddProduct(&jac[kBlockBones], 0, a_x, s.backward[i].d_bones);
          AddProduct(&jac[kBlockBonesT], 0, a_x, s.backward[i].d_bones_t);
          AddProduct(&jac[kBlockRoot], 0, a_root_pt, s.dxroot_droot[i]);
          AddProduct(&jac[kBlockIntrinsics], 0, a_root_pt, s.dxroot_dk[i]);
        }
      }

      // ---- 3D cycle rows: 3 per sample, small blocks only. ----
      if (cycle3d && !gradient) {
        using J = JetN<kPointPoseIntrinsics>;
        for (int i = 0; i < n; ++i) {
          const int row0 = R + 3 * i;
          Eigen::Vector3d q;
          WarpJacobian qj;
          WarpWithJacobian(WarpDirection::kForward, B, bones, p.block[kBlockBonesT],
                           s.x_star.col(i).data(), q.data(), &qj, fw_logits(s.fw_offset + i));
          J qj_jet[3], pose[kPoseSize], k[kIntrinsicsSize], res[3];
          SeedJets(q.data(), 3, 0, qj_jet);
          SeedJets(p.block[kBlockRoot], kPoseSize, 3, pose);
          SeedJets(intr, kIntrinsicsSize, 3 + kPoseSize, k);
          Cycle3dResidual(Cycle3dLoss(tau[i], weights[LossTerm::kCycle3d]), pose, p.root_init, k,
                          ray.uv.data(), ray.samples.depths[i], qj_jet, res);
          Eigen::Matrix<double, 3, kPointPoseIntrinsics> E;
          for (int c = 0; c < 3; ++c) {
            ev.residuals[row0 + c] = res[c].a;
            E.row(c) = res[c].v.transpose();
          }
          const Eigen::Matrix3d a_q = E.leftCols<3>();
          AddProduct(&jac[kBlockRoot], row0, E.middleCols<kPoseSize>(3),
                     Eigen::Matrix<double, kPoseSize, kPoseSize>::Identity());
          AddProduct(&jac[kBlockIntrinsics], row0, E.rightCols<kIntrinsicsSize>(),
                     Eigen::Matrix<double, kIntrinsicsSize, kIntrinsicsSize>::Identity());
          RowMajorMatrix a_x = a_q * qj.d_x;
          AddProduct(&jac[kBlockBones], row0, a_q, qj.d_bones);
          AddProduct(&jac[kBlockBonesT], row0, a_q, qj.d_bones_t);
          if (delta != nullptr) {
            chain_delta(a_q, qj, fw, s.fw_offset + i, kBlockRestPoseCode, row0,
                        s.c3_dfw.middleRows(3 * i, 3), a_x);
          }
          RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
          if (delta != nullptr) {
            chain_delta(a_x, s.backward[i], bw, s.field_offset + i, kBlockPoseCode, row0,
                        s.c3_dbw.middleRows(3 * i, 3), a_root_pt);
          }
          AddProduct(&jac[kBlockBones], row0, a_x, s.backward[i].d_bones);
          AddProduct(&jac[kBlockBonesT], row0, a_x, s.backward[i].d_bones_t);
          AddProduct(&jac[kBlockRoot], row0, a_root_pt, s.dxroot_droot[i]);
          AddProduct(&jac[kBlockIntrinsics], row0, a_root_pt, s.dxroot_dk[i]);
        }
      }
    }
  });
  if (!jacobians) return;

  if (gradient) {
    // Pass 4, gradient mode: ONE backward pass per MLP over the whole
    // minibatch (a single group) with the rays' cotangent rows.
    Eigen::VectorXd d_sdf = Eigen::VectorXd::Zero(total_samples);
    Eigen::Matrix3Xd d_rgb = Eigen::Matrix3Xd::Zero(3, total_samples);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      if (s.render_rows == 0) continue;
      for (int i = 0; i < s.num_samples; ++i) {
        d_sdf(s.field_offset + i) = s.a_sdf(0, i);
        for (int c = 0; c < 3; ++c) d_rgb(c, s.field_offset + i) = s.a_rgb(0, 3 * i + c);
      }
    }
    Eigen::MatrixXd d_sdf_params, d_color_params, d_embedding_params;
    field.BackwardBatch(sdf_params, color_params, fb, d_sdf, d_rgb, {0, total_samples},
                        &d_sdf_params, &d_color_params);
    (*mlp_gradient)[0] = d_sdf_params.col(0);
    (*mlp_gradient)[1] = d_color_params.col(0);
    (*mlp_gradient)[2] = Eigen::VectorXd::Zero(model.embedding_size());
    if (total_match > 0) {
      Eigen::MatrixXd d_psi = Eigen::MatrixXd::Zero(kEmbeddingFeatureDim, total_match);
      for (int r = 0; r < num_rays; ++r) {
        const RayScratch& s = scratch[r];
        if (s.render_rows == 0 || s.num_match == 0) continue;
        const Eigen::MatrixXd psi = eb.psi.middleCols(s.match_offset, s.num_match);
        const Eigen::Matrix3Xd points = eb.x.middleCols(s.match_offset, s.num_match);
        const Eigen::Vector3d a = s.a_xhat.row(0).transpose();
        Eigen::MatrixXd dpsi;
        SoftArgmaxBackward(rays[r]->feature.data(), psi.data(), points.data(), s.num_match,
                           options_.matcher.temperature, a.data(), &dpsi, nullptr);
        d_psi.middleCols(s.match_offset, s.num_match) = dpsi;
      }
      field.BackwardEmbeddingBatch(embedding_params, eb, d_psi, {0, total_match},
                                   &d_embedding_params);
      (*mlp_gradient)[2] = d_embedding_params.col(0);
    }
    if (delta != nullptr) {
      Eigen::MatrixXd d_bw, d_fw, g;
      GatherDeltaAdjoints(scratch, fw_groups, B, 0, &d_bw, &d_fw, nullptr);
      delta->BackwardBatch(delta_params, bw, d_bw, {0, total_samples}, &g);
      (*mlp_gradient)[3] = g.col(0);
      if (total_fw > 0) {
        delta->BackwardBatch(delta_params, fw, d_fw, {0, total_fw}, &g);
        (*mlp_gradient)[3] += g.col(0);
      }
    }
    return;
  }

  // Pass 4 (batched): MLP weight Jacobians, one backward pass per residual
  // row over the whole minibatch, grouped per ray.
  int max_rows = 0;
  for (const RayScratch& s : scratch) max_rows = std::max(max_rows, s.render_rows);
  Eigen::VectorXd d_sdf(total_samples);
  Eigen::Matrix3Xd d_rgb(3, total_samples);
  Eigen::MatrixXd d_sdf_params, d_color_params, d_embedding_params;
  Eigen::MatrixXd d_psi(kEmbeddingFeatureDim, total_match);
  for (int k = 0; k < max_rows; ++k) {
    d_sdf.setZero();
    d_rgb.setZero();
    bool any_field = false;
    bool any_match = false;
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      if (k >= s.render_rows) continue;
      for (int i = 0; i < s.num_samples; ++i) {
        d_sdf(s.field_offset + i) = s.a_sdf(k, i);
        for (int c = 0; c < 3; ++c) d_rgb(c, s.field_offset + i) = s.a_rgb(k, 3 * i + c);
      }
      any_field = any_field || s.a_sdf.row(k).squaredNorm() > 0 || s.a_rgb.row(k).squaredNorm() > 0;
      any_match = any_match || (s.num_match > 0 && s.a_xhat.row(k).squaredNorm() > 0);
    }
    if (any_field) {
      field.BackwardBatch(sdf_params, color_params, fb, d_sdf, d_rgb, field_groups, &d_sdf_params,
                          &d_color_params);
      for (int r = 0; r < num_rays; ++r) {
        if (k >= scratch[r].render_rows) continue;
        (*out)[r].jacobians[kBlockSdf].row(k) = d_sdf_params.col(r).transpose();
        (*out)[r].jacobians[kBlockColor].row(k) = d_color_params.col(r).transpose();
      }
    }
    if (any_match) {
      d_psi.setZero();
      for (int r = 0; r < num_rays; ++r) {
        const RayScratch& s = scratch[r];
        if (k >= s.render_rows || s.num_match == 0) continue;
        const Eigen::MatrixXd psi = eb.psi.middleCols(s.match_offset, s.num_match);
        const Eigen::Matrix3Xd points = eb.x.middleCols(s.match_offset, s.num_match);
        const Eigen::Vector3d a = s.a_xhat.row(k).transpose();
        Eigen::MatrixXd dpsi;
        SoftArgmaxBackward(rays[r]->feature.data(), psi.data(), points.data(), s.num_match,
                           options_.matcher.temperature, a.data(), &dpsi, nullptr);
        d_psi.middleCols(s.match_offset, s.num_match) = dpsi;
      }
      field.BackwardEmbeddingBatch(embedding_params, eb, d_psi, match_groups, &d_embedding_params);
      for (int r = 0; r < num_rays; ++r) {
        if (k >= scratch[r].render_rows || scratch[r].num_match == 0) continue;
        (*out)[r].jacobians[kBlockEmbedding].row(k) = d_embedding_params.col(r).transpose();
      }
    }
    if (delta != nullptr) {
      Eigen::MatrixXd d_bw, d_fw, g_bw, g_fw;
      bool any = false;
      GatherDeltaAdjoints(scratch, fw_groups, B, k, &d_bw, &d_fw, &any);
      if (any) {
        delta->BackwardBatch(delta_params, bw, d_bw, field_groups, &g_bw);
        if (total_fw > 0) delta->BackwardBatch(delta_params, fw, d_fw, fw_groups, &g_fw);
        for (int r = 0; r < num_rays; ++r) {
          if (k >= scratch[r].render_rows) continue;
          auto row = (*out)[r].jacobians[kBlockDeltaSkin].row(k);
          row = g_bw.col(r).transpose();
          if (total_fw > 0) row += g_fw.col(r).transpose();
        }
      }
    }
  }

  // MLP_Delta weight Jacobians of the 3D-cycle rows: row (i, c) of a ray
  // depends on two batch columns only (the backward warp at sample i, the
  // forward warp of X*_i), so for each sample index i the rays' two columns
  // are re-evaluated as a compact batch (one group per ray) and differentiated
  // once per coordinate c, instead of a pass over the whole minibatch per row.
  if (delta != nullptr) {
    int max_n = 0;
    for (const RayScratch& s : scratch) {
      if (s.c3_dbw.rows() > 0) max_n = std::max(max_n, s.num_samples);
    }
    for (int i = 0; i < max_n; ++i) {
      std::vector<int> members;
      for (int r = 0; r < num_rays; ++r) {
        if (scratch[r].c3_dbw.rows() > 0 && i < scratch[r].num_samples) members.push_back(r);
      }
      const int m = static_cast<int>(members.size());
      DeltaSkinningBatch cb, cf;
      cb.x.resize(3, m);
      cb.codes.resize(P, m);
      cf.x.resize(3, m);
      cf.codes.resize(P, m);
      for (int j = 0; j < m; ++j) {
        const RayScratch& s = scratch[members[j]];
        cb.x.col(j) = bw.x.col(s.field_offset + i);
        cb.codes.col(j) = bw.codes.col(s.field_offset + i);
        cf.x.col(j) = fw.x.col(s.fw_offset + i);
        cf.codes.col(j) = fw.codes.col(s.fw_offset + i);
      }
      delta->ForwardBatch(delta_params, &cb, false);
      delta->ForwardBatch(delta_params, &cf, false);
      std::vector<int> groups(m + 1);
      for (int j = 0; j <= m; ++j) groups[j] = j;
      Eigen::MatrixXd d_b(B, m), d_f(B, m), g_b, g_f;
      for (int c = 0; c < 3; ++c) {
        for (int j = 0; j < m; ++j) {
          const RayScratch& s = scratch[members[j]];
          d_b.col(j) = s.c3_dbw.row(3 * i + c).transpose();
          d_f.col(j) = s.c3_dfw.row(3 * i + c).transpose();
        }
        delta->BackwardBatch(delta_params, cb, d_b, groups, &g_b);
        delta->BackwardBatch(delta_params, cf, d_f, groups, &g_f);
        for (int j = 0; j < m; ++j) {
          RayEvaluation& ev = (*out)[members[j]];
          const int row = ev.term_row[static_cast<int>(LossTerm::kCycle3d)] + 3 * i + c;
          ev.jacobians[kBlockDeltaSkin].row(row) = (g_b.col(j) + g_f.col(j)).transpose();
        }
      }
    }
  }
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
