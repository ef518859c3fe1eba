// Automatic model sizing (docs/solver.md "Automatic model sizing"):
// the model starts small and, at the fractions model.auto_size.grow_at of
// the first stage, grows where the residuals stay high.
//
// A grow step:
//  1. draws auto_size.eval_rays rays (RaySampler, the solver's generator,
//     no active sampling) and renders them with the current model;
//  2. per ray r: error e_r = |r_rgb|^2 + |r_sil|^2 (unit weights), sample
//     weights omega_i = tau_i + 1e-3 / N (the rendering weights plus a small
//     floor, so a ray that misses the surface still points at the bones it
//     passes), and the attribution to bone b
//       a_rb = sum_i omega_i w_b(x_i) / sum_i omega_i,
//     w_b(x_i) the backward skinning weights of sample i at time t (sum_b
//     a_rb = 1);
//  3. over the object rays (mask 1, or rendered opacity >= 0.5: rays that
//     see the object in the data or in the model; correctly empty
//     background rays would only dilute the shares), per bone: mass share
//     m_b = sum_r a_rb / R, error share E_b = sum_r e_r a_rb / sum_r e_r,
//     ratio E_b / m_b (the mean error of the bone's rays over the mean
//     error of all object rays);
//  4. bones with ratio >= auto_size.error_ratio and at least
//     kMinSplitRays rays' worth of mass are split, largest ratio first,
//     while B < auto_size.max_bones (SplitBoneGeometry: two moment-matched
//     copies along the principal axis of the bone's error, the offset that
//     changes the warps least among kSplitOffsets; both copies keep the
//     bone's per-frame transforms, so the warps change only through the
//     redistribution of skinning weights);
//  5. if no bone was split and auto_size.max_width is above a width, the
//     SDF and colour MLPs are widened (doubled, capped at max_width) by
//     Net2WiderNet (field/mlp_widen.h; the new units' incoming weights get
//     kWidenNoise relative noise to break the replicas' symmetry).
// Parameters move to new blocks: the caller rebuilds its ceres::Problem and
// carries its optimiser moments over with the returned remaps.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "banmo/losses/ray_batch.h"
#include "banmo/model/model.h"
#include "banmo/optim/config.h"
#include "banmo/optim/ray_sampler.h"

namespace banmo {

// Bones with less mass than this many rays are never split (their ratio is
// noise).
inline constexpr double kMinSplitRays = 8.0;
// Split offsets tried (fractions a of the bone's conditional standard
// deviation along the split axis; a = sqrt(3)/2 halves it).
inline constexpr double kSplitOffsets[] = {0.5, 0.6, 0.7, 0.8, 0.8660254037844386};
// Relative noise on the incoming weights of the units a widening adds.
inline constexpr double kWidenNoise = 0.01;

// The rest bones and every frame's bone transforms of a model (a snapshot,
// or a proposal before it is written back).
struct BoneSet {
  int num_bones = 0;
  std::vector<double> bones;                              // kBoneSize B
  std::vector<std::vector<std::vector<double>>> bones_t;  // [video][frame]: kPoseSize B

  static BoneSet Of(const Model& model);
  // Writes the set into the model (Model::SetBones and every bones_t).
  void WriteTo(Model* model) const;
};

// One evaluation ray reduced to what a grow step needs.
struct SurfacePoint {
  int video = 0, frame = 0;
  Eigen::Vector3d posed = Eigen::Vector3d::Zero();      // omega-weighted sample, root frame at t
  Eigen::Vector3d canonical = Eigen::Vector3d::Zero();  // omega-weighted backward warps
  double opacity = 0.0;                                 // sum_i tau_i
  double error = 0.0;                                   // e_r
  double mask = -1.0;                                   // the ray's mask (< 0 unknown)
  std::vector<double> attribution;                      // a_rb (B values, sum 1)
};

// Per-ray surface points of evaluated rays (`evaluations` from a RayBatch
// with rgb and silhouette terms, in the order of `rays`).
std::vector<SurfacePoint> SurfacePoints(const Model& model, const std::vector<Ray>& rays,
                                        const std::vector<RayEvaluation>& evaluations);

struct BoneAttribution {
  std::vector<double> mass_share;   // m_b
  std::vector<double> error_share;  // E_b
  std::vector<double> ratio;        // E_b / m_b (0 when m_b = 0)
  double mean_error = 0.0;          // mean e_r
};
BoneAttribution AttributeErrors(const std::vector<SurfacePoint>& points, int num_bones);
// The object rays of step 3: mask > 0.5 or opacity >= 0.5.
std::vector<SurfacePoint> ObjectRays(const std::vector<SurfacePoint>& points);

// Two bones replacing `bone` (kBoneSize values each): a Gaussian mixture of
// the two copies with the bone's moments. With the covariance
// S = V diag(s^2) V^T, the unit direction u and sigma_u^2 = 1 / (u^T S^-1 u)
// (the variance along u given the other directions): centres C -+ a sigma_u u,
// covariance S - a^2 sigma_u^2 u u^T each (positive definite for a < 1; the
// mixture's covariance is S). Orientation and log-scales come from that
// covariance's eigen-decomposition.
void SplitBoneGeometry(const double* bone, const Eigen::Vector3d& direction, double offset,
                       double* first, double* second);

// A requested split: bone index (before the step), direction, offset a.
struct BoneSplit {
  int bone = 0;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  double offset = 0.7;
};
// `in` with each split bone replaced by its first copy (same index) and its
// second copy appended (in the order of `splits`); every frame's transform
// of the bone is duplicated for the copy. new_to_old (may be null) gets the
// source bone of every bone of the result.
BoneSet SplitBones(const BoneSet& in, const std::vector<BoneSplit>& splits,
                   std::vector<int>* new_to_old = nullptr);

// How much two bone sets' warps differ at surface points: backward warps of
// the posed points and forward warps of the canonical points, each with its
// frame's transforms (canonical units; GT objects have half-extent ~1).
struct WarpChange {
  double mean_backward = 0.0, max_backward = 0.0;
  double mean_forward = 0.0, max_forward = 0.0;
  int points = 0;
};
WarpChange MeasureWarpChange(const BoneSet& before, const BoneSet& after,
                             const std::vector<SurfacePoint>& points);

// New tangent entry k of a grown block = old entry source[k] times scale[k]
// (gradients; optimiser moments: m' = scale m, v' = scale^2 v).
struct TangentRemap {
  std::vector<int> source;
  std::vector<double> scale;
  // Remaps first and second moments (both empty: nothing to do).
  void Apply(std::vector<double>* m, std::vector<double>* v) const;
};
// By block group: "bones", "bones_t" (every frame's), "sdf", "color".
struct AutoSizeRemaps {
  std::map<std::string, TangentRemap> by_group;
  // The remap of a block named as in Model::ForEachBlock, or null.
  const TangentRemap* For(const std::string& block_name) const;
};

// What a grow step measured and did.
struct AutoSizeEvent {
  int stage = 0, batch = 0;  // filled by the solver
  double seconds = 0.0;      // wall time, with the problem rebuild (filled by the solver)
  int rays = 0;              // evaluation rays
  int object_rays = 0;       // of which object rays (attribution)
  double mean_error = 0.0;   // mean e_r of the object rays
  int bones_before = 0, bones_after = 0;
  int sdf_width_before = 0, sdf_width_after = 0;
  int color_width_before = 0, color_width_after = 0;
  BoneAttribution attribution;
  std::vector<BoneSplit> splits;  // in the order applied
  std::vector<double> split_ratios;
  WarpChange warp;  // of all splits together (zero without splits)
  double sdf_change_mean = 0.0, sdf_change_max = 0.0;  // widening, at the surface points
  bool grew() const {
    return bones_after != bones_before || sdf_width_after != sdf_width_before ||
           color_width_after != color_width_before;
  }
  std::string Describe() const;  // one line for the log
};

// One grow step (the header comment). `model` changes in place; `remaps`
// gets the remaps of the grown blocks.
AutoSizeEvent AutoSizeGrow(const AutoSizeOptions& options, const RaySampler& sampler,
                           const SamplingConfig& sampling, int samples_per_ray,
                           const Eigen::AlignedBox3d& bounds, std::mt19937* rng, Model* model,
                           AutoSizeRemaps* remaps);

}  // namespace banmo
