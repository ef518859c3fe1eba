// The templated stages of a ray's evaluation. Each is written once and used
// twice: with Jets over a stage's few local variables in the mixed-mode path
// (losses/ray_batch.h) and with Jets over every parameter in the full-Jet
// reference (losses/ray_reference.h).
//
// Frames: x_in_cam = camera coordinates of frame t; x_in_root = the object's
// root frame at time t; canonical = rest space. camera_from_root G^t =
// G0^t * dG^t, G0^t data, dG^t the root_delta parameter block: the paper's
// Eq. 20 with the correction on the object side (docs/solver.md, "Root
// poses"), so that turning the object about its own centre is one small
// rotation of dG^t, not a rotation plus a translation of about 2 d sin(phi/2).
#pragma once

#include <cmath>

#include "banmo/geometry/camera.h"
#include "banmo/geometry/se3.h"
#include "banmo/losses/cycle_2d_loss.h"
#include "banmo/losses/cycle_3d_loss.h"
#include "banmo/losses/feature_match_loss.h"
#include "banmo/losses/feature_render_loss.h"
#include "banmo/losses/flow_loss.h"
#include "banmo/losses/ray.h"
#include "banmo/losses/rgb_loss.h"
#include "banmo/losses/sample_weight.h"
#include "banmo/losses/silhouette_loss.h"
#include "banmo/volume/volume_rendering.h"

namespace banmo {

// G^t = G0^t * dG^t.
template <typename T>
inline void RootPose(const T* root_delta, const double* root_init, T* camera_from_root) {
  T init[kPoseSize];
  for (int k = 0; k < kPoseSize; ++k) init[k] = T(root_init[k]);
  PoseCompose(init, root_delta, camera_from_root);
}

// Sample point of a ray at camera depth z: x_in_cam = z K^{-1} [u v 1]^T.
template <typename T>
inline void SampleInCamera(const T* intrinsics, const double* uv, double depth, T* x_in_cam) {
  const T uv_t[2] = {T(uv[0]), T(uv[1])};
  T dir[3];
  PixelToRayDirection(intrinsics, uv_t, dir);
  for (int k = 0; k < 3; ++k) x_in_cam[k] = T(depth) * dir[k];
}

// x_in_root = (G^t)^{-1} x_in_cam for the ray sample at depth z.
template <typename T>
inline void SampleInRoot(const T* root_delta, const double* root_init, const T* intrinsics,
                         const double* uv, double depth, T* x_in_root) {
  T camera_from_root[kPoseSize], x_in_cam[3];
  RootPose(root_delta, root_init, camera_from_root);
  SampleInCamera(intrinsics, uv, depth, x_in_cam);
  PoseInverseTransformPoint(camera_from_root, x_in_cam, x_in_root);
}

// Unit viewing direction of the ray (camera towards the scene) in the root
// frame; the colour MLP's view input (Eq. 1). Not warped by the bones.
template <typename T>
inline void ViewDirectionInRoot(const T* root_delta, const double* root_init, const T* intrinsics,
                                const double* uv, T* view_in_root) {
  using std::sqrt;
  T camera_from_root[kPoseSize], dir[3], d[3];
  RootPose(root_delta, root_init, camera_from_root);
  const T uv_t[2] = {T(uv[0]), T(uv[1])};
  PixelToRayDirection(intrinsics, uv_t, dir);
  PoseInverseRotateVector(camera_from_root, dir, d);
  const T norm = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  for (int k = 0; k < 3; ++k) view_in_root[k] = d[k] / norm;
}

// uv = Pi(G^t x_in_root): project a root-frame point into frame t.
template <typename T>
inline void ProjectRootPoint(const T* root_delta, const double* root_init, const T* intrinsics,
                             const T* x_in_root, T* uv) {
  T camera_from_root[kPoseSize], x_in_cam[3];
  RootPose(root_delta, root_init, camera_from_root);
  PoseTransformPoint(camera_from_root, x_in_root, x_in_cam);
  ProjectPoint(intrinsics, x_in_cam, uv);
}

// 3D cycle residual of one sample (Eq. 19): the forward-warped canonical
// point (already in the root frame, x_cycled_in_root) is mapped to the camera
// and compared with the sample point itself.
template <typename T>
inline void Cycle3dResidual(const Cycle3dLoss& loss, const T* root_delta, const double* root_init,
                            const T* intrinsics, const double* uv, double depth,
                            const T* x_cycled_in_root, T* residual) {
  T camera_from_root[kPoseSize], cycled_in_cam[3], sample_in_cam[3];
  RootPose(root_delta, root_init, camera_from_root);
  PoseTransformPoint(camera_from_root, x_cycled_in_root, cycled_in_cam);
  SampleInCamera(intrinsics, uv, depth, sample_in_cam);
  loss(cycled_in_cam, sample_in_cam, residual);
}

// Local variables of the composite functor, as offsets into one flat vector u.
// Parts that a ray does not need have size 0.
struct CompositeLocals {
  int num_samples = 0;
  int sdf = 0, rgb = 0, canonical = 0, displacement = 0, log_beta = 0, matched = 0,
      cycle_projection = 0, embedding = 0;
  int size = 0;
  bool has_rgb = false, has_displacement = false, has_matched = false, has_cycle = false,
       has_embedding = false;
  // Size of psi_i, the canonical embedding of one sample (FeatureRenderLoss).
  static constexpr int kEmbeddingDim = FeatureRenderLoss::kNumResiduals;

  // Layout: [sdf (N) | rgb (3N) | canonical X*_i (3N) | displacement (2N) |
  //          log_beta (1) | matched X_hat* (3) | cycle projection (2) |
  //          embedding psi(X*_i) (16N)].
  static CompositeLocals For(const Ray& ray, const RayLossWeights& weights);
};

// Everything of a ray downstream of the per-sample field values and warps:
// composites the samples into the pixel's predictions by volume rendering
// (Eqs. 4-7: colour, opacity, expected positions and flow, embedding) and
// evaluates the rgb, silhouette, flow, feature-match, 2D-cycle and
// rendered-embedding residuals (Eqs. 16-18) of the ray's active terms, in
// LossTerm order. The colour and the flow sum only samples of weight tau_i
// >= kMinWarpTau (losses/sample_weight.h): the other samples' colours and
// displacements are not read.
// Input u laid out as CompositeLocals. (Names: docs/design.md, "Names".)
class RayCompositeFunctor {
 public:
  RayCompositeFunctor(const Ray& ray, const RayLossWeights& weights, DensityModel density)
      : ray_(ray),
        weights_(weights),
        density_(density),
        locals_(CompositeLocals::For(ray, weights)) {
    for (int t = 0; t < kNumCompositeTerms; ++t) {
      const LossTerm term = RayTerm(t);
      active_[t] = ray.HasTerm(term, weights);
      if (active_[t]) num_residuals_ += LossTermResiduals(term, ray.NumSamples());
    }
  }

  const CompositeLocals& locals() const { return locals_; }
  int num_residuals() const { return num_residuals_; }
  bool active(LossTerm term) const { return active_[static_cast<int>(term)]; }

  template <typename T>
  bool operator()(const T* u, T* residual) const {
    return Evaluate(u, residual, /*skip_feature_render=*/false);
  }

  // operator() with the option to leave the feature_render rows untouched:
  // when its derivatives wrt the SDF values and log beta are not wanted
  // (losses.feature_render_embedding_only), EmbeddingJacobian gives its
  // values and the rest of its Jacobian without Jets.
  template <typename T>
  bool Evaluate(const T* u, T* residual, bool skip_feature_render) const {
    const int n = locals_.num_samples;
    std::vector<T> tau(n);
    CompositeWeights(n, u + locals_.sdf, u[locals_.log_beta], ray_.samples.deltas.data(), density_,
                     tau.data());
    int row = 0;
    if (active(LossTerm::kRgb)) {
      T color[3] = {T(0), T(0), T(0)};
      for (int i = 0; i < n; ++i) {
        if (!WarpsSample(tau[i])) continue;  // weight below kMinWarpTau: left out
        for (int k = 0; k < 3; ++k) color[k] += tau[i] * u[locals_.rgb + 3 * i + k];
      }
      RgbLoss(ray_.rgb, weights_[LossTerm::kRgb])(color, residual + row);
      row += RgbLoss::kNumResiduals;
    }
    if (active(LossTerm::kSilhouette)) {
      T opacity(0);
      for (int i = 0; i < n; ++i) opacity += tau[i];
      SilhouetteLoss(ray_.mask, weights_[LossTerm::kSilhouette] * ray_.silhouette_weight)(
          &opacity, residual + row);
      row += SilhouetteLoss::kNumResiduals;
    }
    if (active(LossTerm::kFlow)) {
      T displacement[2] = {T(0), T(0)};
      for (int i = 0; i < n; ++i) {
        if (!WarpsSample(tau[i])) continue;  // weight below kMinWarpTau: left out
        for (int k = 0; k < 2; ++k) displacement[k] += tau[i] * u[locals_.displacement + 2 * i + k];
      }
      FlowLoss(ray_.flow, weights_[LossTerm::kFlow])(displacement, residual + row);
      row += FlowLoss::kNumResiduals;
    }
    if (active(LossTerm::kFeatureMatch)) {
      T expected[3] = {T(0), T(0), T(0)};
      for (int i = 0; i < n; ++i) {
        for (int k = 0; k < 3; ++k) expected[k] += tau[i] * u[locals_.canonical + 3 * i + k];
      }
      FeatureMatchLoss(weights_.Weight(LossTerm::kFeatureMatch))(u + locals_.matched, expected,
                                                                 residual + row);
      row += FeatureMatchLoss::kNumResiduals;
    }
    if (active(LossTerm::kCycle2d)) {
      Cycle2dLoss(ray_.uv, weights_[LossTerm::kCycle2d])(u + locals_.cycle_projection,
                                                         residual + row);
      row += Cycle2dLoss::kNumResiduals;
    }
    if (active(LossTerm::kFeatureRender) && !skip_feature_render) {
      constexpr int E = CompositeLocals::kEmbeddingDim;
      T rendered[E];
      for (int k = 0; k < E; ++k) rendered[k] = T(0);
      for (int i = 0; i < n; ++i) {
        if (!WarpsSample(tau[i])) continue;  // weight below kMinWarpTau: left out
        for (int k = 0; k < E; ++k) rendered[k] += tau[i] * u[locals_.embedding + E * i + k];
      }
      FeatureRenderLoss(ray_.feature, weights_[LossTerm::kFeatureRender])(rendered, residual + row);
      row += FeatureRenderLoss::kNumResiduals;
    }
    return true;
  }

  // The rendered-embedding rows' derivatives wrt the embedding inputs, in
  // closed form: rendered = sum_i tau_i psi_i (over tau_i >= kMinWarpTau, as
  // operator()), so d r / d psi_i = tau_i dFeatureRenderLoss/d rendered (one
  // 16 x 16 Jet evaluation), and 0 at the samples left out. The
  // embedding inputs enter no other term, so the Jets of operator() need
  // not carry these 16 N directions (ChunkedJacobian's num_seeded); the
  // full-Jet reference (ray_reference.cc) checks the two agree. jacobian:
  // 16 x 16 N, the block of the feature_render rows and embedding columns;
  // residual (may be null): the 16 rows' values.
  void EmbeddingJacobian(
      const double* u,
      Eigen::Ref<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> jacobian,
      double* residual_values) const {
    constexpr int E = CompositeLocals::kEmbeddingDim;
    using J = ceres::Jet<double, E>;
    const int n = locals_.num_samples;
    std::vector<double> tau(n);
    CompositeWeights(n, u + locals_.sdf, u[locals_.log_beta], ray_.samples.deltas.data(), density_,
                     tau.data());
    J rendered[E], residual[E];
    for (int k = 0; k < E; ++k) {
      double e = 0.0;
      for (int i = 0; i < n; ++i) {
        if (WarpsSample(tau[i])) e += tau[i] * u[locals_.embedding + E * i + k];
      }
      rendered[k] = J(e, k);
    }
    FeatureRenderLoss(ray_.feature, weights_[LossTerm::kFeatureRender])(rendered, residual);
    for (int i = 0; i < n; ++i) {
      const double t = WarpsSample(tau[i]) ? tau[i] : 0.0;
      for (int j = 0; j < E; ++j) {
        for (int k = 0; k < E; ++k) jacobian(j, E * i + k) = t * residual[j].v[k];
      }
    }
    if (residual_values != nullptr) {
      for (int j = 0; j < E; ++j) residual_values[j] = residual[j].a;
    }
  }

 private:
  const Ray& ray_;
  const RayLossWeights weights_;
  const DensityModel density_;
  const CompositeLocals locals_;
  bool active_[kNumCompositeTerms] = {};
  int num_residuals_ = 0;
};

}  // namespace banmo
