// Bone motion registration on feature matches (docs/solver.md, "Bone
// registration").
//
// After a bone re-initialisation every bone transform J_b^t is the identity,
// and the minibatches rebuild the motion from a few rays per frame and
// batch. The registration gives them a start from the data instead:
//
// 1. Proxy: the current canonical surface (marching cubes), a random subset
//    of its vertices, their skinning weights with the rest bones (bones of
//    weight below kRegistrationWeightCutoff left out, the rest renormalised)
//    and, for each pair of bones that both weigh more than joint_min_weight
//    at some vertices, up to joint_points of those vertices.
// 2. Mean-feature embedding: each proxy vertex gets the normalised mean of
//    the pixel features it is seen on (z-buffer of all surface vertices,
//    object pixels only) in every frame, posed with the model's current
//    motion. Unlike the learnt embedding (trained by the soft-argmax match
//    losses only, it follows whatever motion the bones have), it is
//    regressed on the features themselves: on the default scene its hard
//    matches sit 1.8 px from the oracle motion's projections against 6 px
//    for the learnt one (benchmarks/articulation/README.md).
// 3. Matches: up to match_pixels object pixels of each frame, each matched
//    to the proxy vertex of the most similar (cosine) embedding.
// 4. Per video, frame after frame (each frame starting from the previous
//    frame's fit, its own current transforms, or the cheaper of the two:
//    config.start), Levenberg-Marquardt on the frame's B bone transforms
//    (each turning about its rest centre, MakeStackedPivotPoseManifold), the
//    root pose fixed, residuals in pixels:
//      match   the projection of sum_b w_b J_b x (then G^t) minus its
//              matched pixel, Huber(huber_px), weight match_weight / n;
//      joint   J_a x - J_b x at the shared points of each bone pair, weight
//              joint_weight / (all shared points), times the pixels per
//              model unit at the root's depth;
//      smooth  each bone's turn (rad) and centre travel against the
//              previous frame's fit (a video's first frame: the identity),
//              weight smooth_weight / B, in the same pixel units;
//      rest    the same against the identity, weight rest_weight / B;
//      mask    (mask_weight > 0) the distance from the projection of each of
//              mask_points fitted vertices to the frame's mask (0 inside),
//              Huber(huber_px), weight mask_weight / mask_points: every
//              vertex, seen or not, projects into the silhouette, which
//              constrains the parts no match sees (a wing seen edge-on).
//              It asks for containment, not coverage: a part no match
//              holds may also fold toward the camera to fit (tests).
//      coverage (coverage_weight > 0) each of coverage_pixels object
//              pixels of the frame tied to the fitted vertex whose
//              projection is nearest, the projection minus the pixel,
//              Huber(huber_px), weight coverage_weight / coverage_pixels:
//              the silhouette's counterpart of the mask term (every
//              object pixel covered by some vertex), which unfolds what
//              containment lets fold. The ties are remade from the fit
//              coverage_rounds times (2D ICP; each round a Levenberg-
//              Marquardt solve of iterations / coverage_rounds iterations).
//
// Deterministic: subsets and pixels are drawn from `seed`; videos run in
// parallel, each on its own.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/model/model.h"
#include "banmo/registration/bone_registration_config.h"

namespace ceres {
class CostFunction;
}

namespace banmo {

// Skinning weights below this are left out of a proxy vertex's blend (the
// kept ones renormalised): the vertex then moves by at most this times the
// largest distance between two bones' images of it, 0.02 px for bones 1
// model unit apart at 200 px per unit.
inline constexpr double kRegistrationWeightCutoff = 1e-4;

// A canonical point blended from a few bones with fixed weights.
struct SkinnedPoint {
  Eigen::Vector3d x = Eigen::Vector3d::Zero();  // canonical
  std::vector<int> bones;                       // increasing bone indices
  std::vector<double> weights;                  // summing to 1
};

// The SkinnedPoint of canonical point x with the skinning weights w (B of
// them, summing to 1): bones of weight >= kRegistrationWeightCutoff.
SkinnedPoint MakeSkinnedPoint(const Eigen::Vector3d& x, const Eigen::VectorXd& w);

// The pixel of a skinned point at frame t minus its matched pixel:
//   r = Project(intrinsics, G^t sum_k w_k J_{b_k}^t x) - target,
// parameter blocks: the bone transforms J_{b_k}^t (kPoseSize each) in the
// order of point.bones. Jacobian by hand (each rotation through Jet<4> on
// its quaternion; the registration's main cost was this residual's
// Jet<14> passes); MakeSkinnedPixelCostFunctionAutoDiff is its autodiff
// twin (tests).
std::unique_ptr<ceres::CostFunction> MakeSkinnedPixelCostFunction(const SkinnedPoint& point,
                                                                  const Pose& camera_from_root,
                                                                  const Eigen::Vector4d& intrinsics,
                                                                  const Eigen::Vector2d& target);
std::unique_ptr<ceres::CostFunction> MakeSkinnedPixelCostFunctionAutoDiff(
    const SkinnedPoint& point, const Pose& camera_from_root, const Eigen::Vector4d& intrinsics,
    const Eigen::Vector2d& target);

// The mask term's image: each pixel's distance (pixels, between pixel
// centres) to the nearest object pixel of `mask` (CV_8UC1, dataset.h
// values), 0 on object and ignored pixels; CV_32FC1. Empty when the mask
// has no object pixel.
cv::Mat MaskOutsideDistance(const cv::Mat& mask);

// The distance image at a skinned point's pixel:
//   r = D(Project(intrinsics, G^t sum_k w_k J_{b_k}^t x)),
// D bicubic-interpolated (ceres::BiCubicInterpolator, clamped at the image
// border) with pixel (i, j)'s value at (i + 0.5, j + 0.5). Parameter blocks
// as MakeSkinnedPixelCostFunction. Jacobian by hand as there (with the
// interpolator's gradient); MakeSkinnedMaskCostFunctionAutoDiff is its
// autodiff twin (tests). Keeps a reference to `distance`'s data (cv::Mat's
// reference count).
std::unique_ptr<ceres::CostFunction> MakeSkinnedMaskCostFunction(const SkinnedPoint& point,
                                                                 const Pose& camera_from_root,
                                                                 const Eigen::Vector4d& intrinsics,
                                                                 const cv::Mat& distance);
std::unique_ptr<ceres::CostFunction> MakeSkinnedMaskCostFunctionAutoDiff(
    const SkinnedPoint& point, const Pose& camera_from_root, const Eigen::Vector4d& intrinsics,
    const cv::Mat& distance);

// Two bones' images of one canonical point m, r = scale (J_a m - J_b m);
// parameter blocks J_a, J_b. Autodiff.
std::unique_ptr<ceres::CostFunction> MakeBonePairCostFunction(const Eigen::Vector3d& m,
                                                              double scale);

// A bone pair's shared points m at once: the residual is linear in the
// homogeneous point [m; 1], so sum_m |scale (J_a m - J_b m)|^2 equals the
// same sum over four homogeneous points x_k = (p_k, w_k) with
// sum_k x_k x_k^T = sum_m [m; 1][m; 1]^T, r_k = scale (R_a p_k + w_k t_a -
// R_b p_k - w_k t_b): 12 residuals for any number of points (the
// registration's pairs hold up to 40: 120 rows), the same value, gradient
// and Gauss-Newton matrix to rounding. Parameter blocks J_a, J_b. Autodiff;
// MakeBonePairCostFunction is its twin.
std::unique_ptr<ceres::CostFunction> MakeBonePairMomentCostFunction(
    const std::vector<Eigen::Vector3d>& points, double scale);

// One bone transform J against a reference J0, both read as a turn R about
// the rest centre c and the centre's travel tau = R c + t - c:
//   r = scale [angle-axis(R R0^T); tau - tau0]   (6 residuals),
// parameter block J. Autodiff.
std::unique_ptr<ceres::CostFunction> MakeBonePriorCostFunction(const Pose& reference,
                                                               const Eigen::Vector3d& centre,
                                                               double scale);

// The proxy of step 1.
struct RegistrationProxy {
  Eigen::Matrix3Xd surface;          // every surface vertex (z-buffer)
  std::vector<int> subset;           // fitted vertices, indices into surface (increasing)
  std::vector<SkinnedPoint> points;  // the fitted vertices, skinned
  struct Pair {
    int a = 0, b = 0;  // a < b
    std::vector<Eigen::Vector3d> points;
  };
  std::vector<Pair> pairs;
};

// Proxy of the canonical surface `surface` (3 x V) with its skinning
// weights (B x V); `count` vertices drawn with `seed`.
RegistrationProxy MakeRegistrationProxy(const Eigen::Matrix3Xd& surface,
                                        const Eigen::MatrixXd& weights, int count,
                                        double joint_min_weight, int joint_points,
                                        std::uint32_t seed);

// Indices (into `points`) of the points a pinhole camera sees: those whose
// depth is within `tolerance` of the nearest point projected to the same
// pixel (pixel (i, j) holds u in [i, i + 1), v in [j, j + 1)), inside the
// width x height image and in front of the camera; their pixels in `pixels`.
std::vector<int> VisiblePoints(const Eigen::Matrix3Xd& points_in_camera,
                               const Eigen::Vector4d& intrinsics, int width, int height,
                               double tolerance, std::vector<Eigen::Vector2i>* pixels);

// Step 2: the mean-feature embedding (kFeatureDim x proxy vertices,
// unit columns; zero for vertices no frame sees). Frames without features
// or marked skip are left out.
Eigen::MatrixXd MeanFeatureEmbedding(const Model& model, const Dataset& dataset,
                                     const RegistrationProxy& proxy, double tolerance);

// Step 3 for one frame: up to `count` object pixels (drawn with `seed`),
// each with the proxy vertex of the most similar embedding.
struct FrameMatches {
  std::vector<int> vertex;             // into proxy.points
  std::vector<Eigen::Vector2d> pixel;  // pixel centres (x + 0.5, y + 0.5)
};
FrameMatches MatchFrameFeatures(const Eigen::MatrixXd& embedding, const Frame& frame, int count,
                                std::uint32_t seed);

// The frame's data of the silhouette terms: either part may be empty (no
// such term).
struct FrameSilhouette {
  cv::Mat outside_distance;                    // MaskOutsideDistance (mask term)
  std::vector<Eigen::Vector2d> object_pixels;  // pixel centres (coverage term)
};

// Up to `count` object pixels of `mask` (CV_8UC1, dataset.h values), drawn
// with `seed`, as pixel centres (x + 0.5, y + 0.5).
std::vector<Eigen::Vector2d> SampleObjectPixels(const cv::Mat& mask, int count, std::uint32_t seed);

// Step 4 for one frame: fits bones_t (kPoseSize B, in and out) from its
// value.
struct FrameRegistrationInputs {
  const RegistrationProxy* proxy = nullptr;
  const FrameMatches* matches = nullptr;
  int num_bones = 0;                       // B > 0
  const double* bones = nullptr;           // the rest bones (kBoneSize B)
  Pose camera_from_root = PoseIdentity();  // the frame's root pose G^t
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();
  // The previous frame's fit (null: the identity), the reference of the
  // smooth term.
  const double* previous = nullptr;
  // The frame's silhouette data (null: no mask or coverage term).
  const FrameSilhouette* silhouette = nullptr;
  // With alternative_start (kPoseSize B) the fit starts from whichever of
  // bones_t's value and alternative_start the terms but the coverage ties
  // (which are made from the start) cost less; bones_t's value wins a tie.
  const double* alternative_start = nullptr;
};
struct FrameRegistration {
  double initial_cost = 0.0;
  double final_cost = 0.0;
  double median_match_px_before = 0.0;  // |match residual|, median
  double median_match_px_after = 0.0;
  int iterations = 0;
  bool started_from_alternative = false;  // alternative_start was the cheaper
};
FrameRegistration RegisterFrameBones(const FrameRegistrationInputs& in,
                                     const BoneRegistrationConfig& config, double* bones_t);

struct BoneRegistrationReport {
  bool registered = false;
  std::string reason;  // why not (registered == false)
  int frames = 0;      // frames registered
  int surface_vertices = 0;
  int pairs = 0;  // bone pairs with shared points
  double seconds = 0.0;
  double median_match_px_before = 0.0;  // over frames (each frame's median)
  double median_match_px_after = 0.0;
  double mean_turn_deg = 0.0;  // bones' mean turn from the rest pose after the fit
  // start lower_cost: frames whose fit started from their own transforms
  // rather than the previous frame's fit (-1: no per-frame choice).
  int own_starts = -1;
  std::string Describe() const;
};

// Steps 1-4 on every usable frame: sets each frame's bones_t (the rest of the
// model is unchanged). Nothing changes when the model has no bones, the
// dataset no features, or the surface is empty (the reason says which).
BoneRegistrationReport RegisterBoneMotion(Model* model, const Dataset& dataset,
                                          const Eigen::AlignedBox3d& bounds,
                                          const BoneRegistrationConfig& config, std::uint32_t seed);

}  // namespace banmo
