// Bone motion registration on feature matches (registration/bone_registration.h):
// the residuals against direct computations, the z-buffer, the
// mean-feature embedding and matches on a rendered point cloud, and the
// per-frame fit recovering a known articulation from exact matches, and the
// mask term (distance image, residual, a fit from the silhouette alone).
#include "banmo/registration/bone_registration.h"

#include <ceres/cost_function.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "banmo/deform/bones.h"
#include "banmo/geometry/camera.h"

namespace banmo {
namespace {

// RegisterFrameBones' inputs without a previous frame, silhouette or
// alternative start.
FrameRegistrationInputs FrameInputs(const RegistrationProxy& proxy, const FrameMatches& matches,
                                    int num_bones, const double* bones, const Pose& g,
                                    const Eigen::Vector4d& k) {
  FrameRegistrationInputs in;
  in.proxy = &proxy;
  in.matches = &matches;
  in.num_bones = num_bones;
  in.bones = bones;
  in.camera_from_root = g;
  in.intrinsics = k;
  return in;
}

constexpr double kDeg = M_PI / 180.0;

std::vector<double> Evaluate(const ceres::CostFunction& cost,
                             const std::vector<const double*>& blocks) {
  std::vector<double> r(cost.num_residuals());
  EXPECT_TRUE(cost.Evaluate(blocks.data(), r.data(), nullptr));
  return r;
}

// A bone transform turning by angle-axis w about centre c, then moving c by
// tau: J x = R (x - c) + c + tau.
Pose TurnAbout(const Eigen::Vector3d& w, const Eigen::Vector3d& c, const Eigen::Vector3d& tau) {
  const Eigen::Matrix3d R = w.norm() > 0
                                ? Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix()
                                : Eigen::Matrix3d::Identity();
  return PoseFromAngleAxis(w, c + tau - R * c);
}

Eigen::Vector3d Apply(const Pose& p, const Eigen::Vector3d& x) {
  Eigen::Vector3d y;
  PoseTransformPoint(p.data(), x.data(), y.data());
  return y;
}

TEST(BoneRegistration, SkinnedPointKeepsBonesAboveTheCutoffRenormalised) {
  Eigen::VectorXd w(4);
  w << 0.6, 0.5 * kRegistrationWeightCutoff, 0.4 - kRegistrationWeightCutoff,
      0.5 * kRegistrationWeightCutoff;
  const SkinnedPoint p = MakeSkinnedPoint(Eigen::Vector3d(1, 2, 3), w);
  ASSERT_EQ(p.bones, (std::vector<int>{0, 2}));
  EXPECT_NEAR(p.weights[0] + p.weights[1], 1.0, 1e-15);
  EXPECT_NEAR(p.weights[0] / p.weights[1], w[0] / w[2], 1e-12);
}

// A point blended from bones 1 and 3 (weights 0.7, 0.3), their transforms,
// a root pose and intrinsics; Pixel() projects the blend directly.
struct SkinnedPointCase {
  SkinnedPoint p;
  Pose j1 = TurnAbout(Eigen::Vector3d(0.1, 0.4, -0.2), Eigen::Vector3d(0, 0.1, 0),
                      Eigen::Vector3d(0.05, 0, 0.02));
  Pose j3 = TurnAbout(Eigen::Vector3d(-0.3, 0.1, 0.2), Eigen::Vector3d(0.3, 0, 0.1),
                      Eigen::Vector3d(0, -0.04, 0));
  Pose g = PoseFromAngleAxis(Eigen::Vector3d(0.2, -0.5, 0.1), Eigen::Vector3d(0.1, 0, 3));
  Eigen::Vector4d k = Eigen::Vector4d(120, 110, 64, 60);

  SkinnedPointCase() {
    p.x = Eigen::Vector3d(0.2, -0.1, 0.3);
    p.bones = {1, 3};
    p.weights = {0.7, 0.3};
  }
  Eigen::Vector2d Pixel() const {
    const Eigen::Vector3d cam = Apply(g, 0.7 * Apply(j1, p.x) + 0.3 * Apply(j3, p.x));
    return Eigen::Vector2d(k[0] * cam.x() / cam.z() + k[2], k[1] * cam.y() / cam.z() + k[3]);
  }
};

// The pixel residual against the blend, root pose and projection computed
// directly; a change of one bone block moves it as predicted.
TEST(BoneRegistration, SkinnedPixelResidualIsTheProjectedBlendMinusTheTarget) {
  const SkinnedPointCase c;
  const SkinnedPoint& p = c.p;
  const Pose &j1 = c.j1, &j3 = c.j3, &g = c.g;
  const Eigen::Vector4d& k = c.k;
  const Eigen::Vector2d target(70.5, 55.5);
  const auto cost = MakeSkinnedPixelCostFunction(p, g, k, target);
  ASSERT_EQ(cost->num_residuals(), 2);
  ASSERT_EQ(cost->parameter_block_sizes().size(), 2u);
  const Eigen::Vector2d uv = c.Pixel();
  const std::vector<double> r = Evaluate(*cost, {j1.data(), j3.data()});
  EXPECT_NEAR(r[0], uv.x() - target.x(), 1e-10);
  EXPECT_NEAR(r[1], uv.y() - target.y(), 1e-10);
  // Golden values (the same formula in numpy and scipy).
  EXPECT_NEAR(r[0], 2.6855346, 1e-6);
  EXPECT_NEAR(r[1], -1.5312148, 1e-6);
}

// Residuals and Jacobians of two cost functions on the same blocks agree:
// values to 1e-12 (relative), Jacobian entries to 1e-9 relative to the
// block's largest entry (both are exact derivatives in double precision;
// the hand-written chain sums in another order).
void ExpectSameJacobians(const ceres::CostFunction& a, const ceres::CostFunction& b,
                         const std::vector<const double*>& blocks) {
  ASSERT_EQ(a.num_residuals(), b.num_residuals());
  ASSERT_EQ(a.parameter_block_sizes(), b.parameter_block_sizes());
  const int m = a.num_residuals();
  const size_t n = blocks.size();
  std::vector<double> ra(m), rb(m);
  std::vector<std::vector<double>> ja(n), jb(n);
  std::vector<double*> pa(n), pb(n);
  for (size_t i = 0; i < n; ++i) {
    ja[i].assign(m * a.parameter_block_sizes()[i], 0.0);
    jb[i].assign(m * a.parameter_block_sizes()[i], 0.0);
    pa[i] = ja[i].data();
    pb[i] = jb[i].data();
  }
  ASSERT_TRUE(a.Evaluate(blocks.data(), ra.data(), pa.data()));
  ASSERT_TRUE(b.Evaluate(blocks.data(), rb.data(), pb.data()));
  for (int r = 0; r < m; ++r) EXPECT_NEAR(ra[r], rb[r], 1e-12 * (1 + std::abs(rb[r])));
  for (size_t i = 0; i < n; ++i) {
    double scale = 0.0;
    for (double v : jb[i]) scale = std::max(scale, std::abs(v));
    ASSERT_GT(scale, 0.0);
    for (size_t e = 0; e < ja[i].size(); ++e) {
      EXPECT_NEAR(ja[i][e], jb[i][e], 1e-9 * scale) << "block " << i << " entry " << e;
    }
  }
  // Some Jacobians asked for: only those are written.
  std::vector<double> only(m * a.parameter_block_sizes()[n - 1], 0.0);
  std::vector<double*> some(n, nullptr);
  some[n - 1] = only.data();
  ASSERT_TRUE(a.Evaluate(blocks.data(), ra.data(), some.data()));
  for (size_t e = 0; e < only.size(); ++e) {
    EXPECT_NEAR(only[e], jb[n - 1][e], 1e-9 * (1 + std::abs(jb[n - 1][e])));
  }
}

// The hand-written Jacobians of the pixel and mask residuals against their
// autodiff twins: the shared point, unnormalised quaternions (the
// residuals normalise them), a point with one bone and with three, and a
// point behind the camera's clamp depth.
TEST(BoneRegistration, SkinnedResidualJacobiansMatchAutodiff) {
  const SkinnedPointCase c;
  cv::Mat d(100, 120, CV_32FC1);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> noise(0.0f, 5.0f);
  for (int r = 0; r < d.rows; ++r) {
    for (int col = 0; col < d.cols; ++col) d.at<float>(r, col) = noise(rng);
  }
  const Eigen::Vector2d target(70.5, 55.5);
  Pose j1 = c.j1, j3 = c.j3;
  for (int i = 0; i < 4; ++i) {
    j1[kPoseQw + i] *= 1.3;
    j3[kPoseQw + i] *= 0.8;
  }
  ExpectSameJacobians(*MakeSkinnedPixelCostFunction(c.p, c.g, c.k, target),
                      *MakeSkinnedPixelCostFunctionAutoDiff(c.p, c.g, c.k, target),
                      {j1.data(), j3.data()});
  ExpectSameJacobians(*MakeSkinnedMaskCostFunction(c.p, c.g, c.k, d),
                      *MakeSkinnedMaskCostFunctionAutoDiff(c.p, c.g, c.k, d),
                      {j1.data(), j3.data()});
  SkinnedPoint one = c.p;
  one.bones = {2};
  one.weights = {1.0};
  ExpectSameJacobians(*MakeSkinnedPixelCostFunction(one, c.g, c.k, target),
                      *MakeSkinnedPixelCostFunctionAutoDiff(one, c.g, c.k, target), {j1.data()});
  SkinnedPoint three = c.p;
  three.bones = {0, 1, 3};
  three.weights = {0.2, 0.5, 0.3};
  const Pose j0 = TurnAbout(Eigen::Vector3d(0.0, -0.2, 0.3), Eigen::Vector3d(0.1, 0.1, 0.1),
                            Eigen::Vector3d(0.0, 0.03, -0.01));
  ExpectSameJacobians(*MakeSkinnedPixelCostFunction(three, c.g, c.k, target),
                      *MakeSkinnedPixelCostFunctionAutoDiff(three, c.g, c.k, target),
                      {j0.data(), j1.data(), j3.data()});
  ExpectSameJacobians(*MakeSkinnedMaskCostFunction(three, c.g, c.k, d),
                      *MakeSkinnedMaskCostFunctionAutoDiff(three, c.g, c.k, d),
                      {j0.data(), j1.data(), j3.data()});
  // Behind the camera: the depth is clamped, its column zero in both.
  const Pose behind = PoseFromAngleAxis(Eigen::Vector3d(0.2, -0.5, 0.1), Eigen::Vector3d(0, 0, -3));
  ExpectSameJacobians(*MakeSkinnedPixelCostFunction(c.p, behind, c.k, target),
                      *MakeSkinnedPixelCostFunctionAutoDiff(c.p, behind, c.k, target),
                      {j1.data(), j3.data()});
}

TEST(BoneRegistration, MaskOutsideDistanceIsZeroOnObjectAndIgnoredPixels) {
  cv::Mat mask(7, 9, CV_8UC1, cv::Scalar(kMaskBackground));
  mask(cv::Rect(2, 2, 2, 3)).setTo(kMaskObject);  // columns 2-3, rows 2-4
  mask.at<unsigned char>(0, 8) = kMaskIgnore;
  const cv::Mat d = MaskOutsideDistance(mask);
  ASSERT_EQ(d.type(), CV_32FC1);
  ASSERT_EQ(d.size(), mask.size());
  EXPECT_EQ(d.at<float>(3, 2), 0.0f);
  EXPECT_EQ(d.at<float>(4, 3), 0.0f);
  EXPECT_EQ(d.at<float>(0, 8), 0.0f);                    // ignored: no pull
  EXPECT_NEAR(d.at<float>(3, 6), 3.0, 1e-4);             // three columns right of the block
  EXPECT_NEAR(d.at<float>(0, 0), std::sqrt(8.0), 1e-4);  // diagonal to (2, 2)
  EXPECT_NEAR(d.at<float>(1, 8), 1.0, 1e-4);             // next to the ignored pixel
  // No object pixel: no distance image (the fit then has no mask term).
  EXPECT_TRUE(MaskOutsideDistance(cv::Mat(5, 5, CV_8UC1, cv::Scalar(kMaskBackground))).empty());
}

TEST(BoneRegistration, SkinnedMaskResidualReadsTheDistanceImageAtThePixel) {
  const SkinnedPointCase c;
  const SkinnedPoint& p = c.p;
  const Pose &j1 = c.j1, &j3 = c.j3, &g = c.g;
  const Eigen::Vector4d& k = c.k;
  // A linear image, which bicubic (Catmull-Rom) interpolation reproduces
  // exactly away from the border: D(row, col) = 2 col + 0.5 row.
  cv::Mat d(100, 120, CV_32FC1);
  for (int r = 0; r < d.rows; ++r) {
    for (int c = 0; c < d.cols; ++c) d.at<float>(r, c) = 2.0f * c + 0.5f * r;
  }
  const auto cost = MakeSkinnedMaskCostFunction(p, g, k, d);
  ASSERT_EQ(cost->num_residuals(), 1);
  ASSERT_EQ(cost->parameter_block_sizes().size(), 2u);
  const Eigen::Vector2d uv = c.Pixel();
  ASSERT_GT(uv.x(), 10);
  ASSERT_GT(uv.y(), 10);
  const std::vector<double> r = Evaluate(*cost, {j1.data(), j3.data()});
  // Pixel (i, j)'s value sits at its centre (i + 0.5, j + 0.5).
  EXPECT_NEAR(r[0], 2.0 * (uv.x() - 0.5) + 0.5 * (uv.y() - 0.5), 1e-9);
  // The data stay alive with the cost function (cv::Mat reference count).
  d.release();
  EXPECT_NEAR(Evaluate(*cost, {j1.data(), j3.data()})[0], r[0], 0.0);
}

// A turn about the rest centre is all rotation; a travel all translation;
// the reference gives zero.
TEST(BoneRegistration, BonePriorSeparatesTurnAboutTheCentreFromTravel) {
  const Eigen::Vector3d c(0.3, -0.2, 0.1);
  const Pose reference =
      TurnAbout(Eigen::Vector3d(0.2, 0.1, 0), c, Eigen::Vector3d(0.01, 0.02, 0.03));
  const auto cost = MakeBonePriorCostFunction(reference, c, 50.0);
  ASSERT_EQ(cost->num_residuals(), 6);
  for (double r : Evaluate(*cost, {reference.data()})) EXPECT_NEAR(r, 0.0, 1e-12);

  const auto from_identity = MakeBonePriorCostFunction(PoseIdentity(), c, 50.0);
  const Eigen::Vector3d w(0.3, -0.2, 0.5);
  const Pose turned = TurnAbout(w, c, Eigen::Vector3d::Zero());
  const std::vector<double> r = Evaluate(*from_identity, {turned.data()});
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(r[i], 50.0 * w[i], 1e-9);
    EXPECT_NEAR(r[3 + i], 0.0, 1e-12);
  }
  const Eigen::Vector3d tau(0.1, 0.0, -0.2);
  const Pose moved = TurnAbout(Eigen::Vector3d::Zero(), c, tau);
  const std::vector<double> s = Evaluate(*from_identity, {moved.data()});
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(s[i], 0.0, 1e-12);
    EXPECT_NEAR(s[3 + i], 50.0 * tau[i], 1e-12);
  }
  // The short way round: q and -q are the same turn.
  Pose flipped = turned;
  flipped.head<4>() *= -1.0;
  const std::vector<double> f = Evaluate(*from_identity, {flipped.data()});
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(f[i], r[i], 1e-9);
}

TEST(BoneRegistration, BonePairIsTheScaledDifferenceOfTheTwoImages) {
  const Eigen::Vector3d m(0.1, 0.2, -0.3);
  const Pose a =
      TurnAbout(Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d::Zero(), Eigen::Vector3d(0.02, 0, 0));
  const Pose b = TurnAbout(Eigen::Vector3d(0, 0.2, 0), Eigen::Vector3d(0.5, 0, 0),
                           Eigen::Vector3d(0, 0.03, 0));
  const auto cost = MakeBonePairCostFunction(m, 7.0);
  const std::vector<double> r = Evaluate(*cost, {a.data(), b.data()});
  const Eigen::Vector3d d = 7.0 * (Apply(a, m) - Apply(b, m));
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(r[i], d[i], 1e-12);
}

// The pair's moment form against a block per point: the same cost,
// gradient and Gauss-Newton matrix J^T J (to 1e-10 relative: sums of 40
// terms against 4), for two, three (coplanar: a singular moment matrix)
// and forty points, in the ambient 7 + 7 parameters.
TEST(BoneRegistration, BonePairMomentsEqualTheSumOverThePoints) {
  const Pose a = TurnAbout(Eigen::Vector3d(0.3, -0.1, 0.2), Eigen::Vector3d(0.1, 0, 0),
                           Eigen::Vector3d(0.02, 0.1, 0));
  const Pose b = TurnAbout(Eigen::Vector3d(-0.2, 0.4, 0.1), Eigen::Vector3d(0.5, 0.2, 0),
                           Eigen::Vector3d(0, 0.03, -0.05));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int count : {2, 3, 40}) {
    std::vector<Eigen::Vector3d> points;
    for (int i = 0; i < count; ++i) {
      points.emplace_back(u(rng), u(rng), count == 3 ? 0.25 : u(rng));
    }
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    double cost_points = 0.0;
    Eigen::VectorXd g_points = Eigen::VectorXd::Zero(14);
    Eigen::MatrixXd h_points = Eigen::MatrixXd::Zero(14, 14);
    auto add = [&](const ceres::CostFunction& f, double* cost, Eigen::VectorXd* g,
                   Eigen::MatrixXd* h) {
      const int rows = f.num_residuals();
      Eigen::VectorXd r(rows);
      RowMajor ja(rows, kPoseSize), jb(rows, kPoseSize);
      const double* params[2] = {a.data(), b.data()};
      double* jacobians[2] = {ja.data(), jb.data()};
      ASSERT_TRUE(f.Evaluate(params, r.data(), jacobians));
      Eigen::MatrixXd j(rows, 14);
      j << ja, jb;
      *cost += r.squaredNorm();
      *g += j.transpose() * r;
      *h += j.transpose() * j;
    };
    for (const Eigen::Vector3d& m : points) {
      add(*MakeBonePairCostFunction(m, 7.0), &cost_points, &g_points, &h_points);
    }
    double cost = 0.0;
    Eigen::VectorXd g = Eigen::VectorXd::Zero(14);
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(14, 14);
    const auto moments = MakeBonePairMomentCostFunction(points, 7.0);
    EXPECT_EQ(moments->num_residuals(), 12);
    add(*moments, &cost, &g, &h);
    ASSERT_GT(cost_points, 0.0);
    EXPECT_NEAR(cost, cost_points, 1e-10 * cost_points) << count << " points";
    EXPECT_LE((g - g_points).cwiseAbs().maxCoeff(), 1e-10 * g_points.cwiseAbs().maxCoeff())
        << count << " points";
    EXPECT_LE((h - h_points).cwiseAbs().maxCoeff(), 1e-10 * h_points.cwiseAbs().maxCoeff())
        << count << " points";
  }
}

TEST(BoneRegistration, VisiblePointsHideWhatIsBehindInTheSamePixel) {
  const Eigen::Vector4d k(100, 100, 32, 32);
  Eigen::Matrix3Xd p(3, 5);
  p.col(0) << 0, 0, 2;         // pixel (32, 32)
  p.col(1) << 0, 0, 2.5;       // same pixel, behind: hidden
  p.col(2) << 0.001, 0, 2.03;  // same pixel, within the tolerance
  p.col(3) << 1, 0, 2;         // u = 82: outside a 64-pixel image
  p.col(4) << 0, 0, -1;        // behind the camera
  std::vector<Eigen::Vector2i> pixels;
  const std::vector<int> visible = VisiblePoints(p, k, 64, 64, 0.05, &pixels);
  ASSERT_EQ(visible, (std::vector<int>{0, 2}));
  EXPECT_EQ(pixels[0], Eigen::Vector2i(32, 32));
  EXPECT_EQ(pixels[1], Eigen::Vector2i(32, 32));
}

// Two bones along a bar; bone 1 turned and moved at frame t. From exact
// matches (each vertex's true pixel) the fit started at the identity
// recovers the transforms: the pixels to 0.01 px, bone 1's turn to 0.1 deg.
// B bone transforms J_b^t at the identity (kPoseSize each).
std::vector<double> IdentityBoneTransforms(int B) {
  std::vector<double> j(kPoseSize * B);
  for (int b = 0; b < B; ++b) PoseSetIdentity(j.data() + kPoseSize * b);
  return j;
}

// Two bones at x = -0.4 and 0.4 and a bar of n random points along them
// with the Gaussian bones' skinning weights.
struct BarScene {
  static constexpr int B = 2;
  std::vector<double> bones;
  Eigen::Matrix3Xd surface;
  Eigen::MatrixXd weights;
};

BarScene MakeBarScene(int n) {
  BarScene bar;
  const int B = BarScene::B;
  bar.bones.resize(kBoneSize * B);
  InitializeBones({Eigen::Vector3d(-0.4, 0, 0), Eigen::Vector3d(0.4, 0, 0)}, 0.3, bar.bones.data());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-1, 1);
  bar.surface.resize(3, n);
  bar.weights.resize(B, n);
  for (int i = 0; i < n; ++i) {
    bar.surface.col(i) = Eigen::Vector3d(0.9 * uni(rng), 0.15 * uni(rng), 0.15 * uni(rng));
    double logits[B];
    for (int b = 0; b < B; ++b) {
      logits[b] = BoneLogit(bar.bones.data() + kBoneSize * b, &bar.surface(0, i));
    }
    SkinningWeights(B, logits, bar.weights.col(i).data());
  }
  return bar;
}

// The bar with both bones moved (bone 1 by 35 deg, mostly about the view
// axis), seen from 3 units, and every proxy vertex matched to its exact
// pixel.
struct ExactMatchCase {
  static constexpr int B = BarScene::B;
  BarScene bar = MakeBarScene(400);
  RegistrationProxy proxy = MakeRegistrationProxy(bar.surface, bar.weights, 300, 0.15, 40, 5);
  std::vector<double> truth = std::vector<double>(kPoseSize * B);
  Pose g = PoseFromAngleAxis(Eigen::Vector3d(0.3, 0, 0), Eigen::Vector3d(0, 0, 3));
  Eigen::Vector4d k = Eigen::Vector4d(300, 300, 128, 128);
  FrameMatches matches;
  ExactMatchCase() {
    Eigen::Map<Pose>(truth.data()) = TurnAbout(
        Eigen::Vector3d(0, 0.05, 0), Eigen::Vector3d(-0.4, 0, 0), Eigen::Vector3d::Zero());
    Eigen::Map<Pose>(truth.data() + kPoseSize) = TurnAbout(
        Eigen::Vector3d(0, 0.1, 0.6), Eigen::Vector3d(0.4, 0, 0), Eigen::Vector3d(0.0, 0.02, 0.0));
    for (size_t i = 0; i < proxy.points.size(); ++i) {
      const SkinnedPoint& p = proxy.points[i];
      Eigen::Vector3d y = Eigen::Vector3d::Zero();
      for (size_t j = 0; j < p.bones.size(); ++j) {
        y += p.weights[j] *
             Apply(Eigen::Map<const Pose>(truth.data() + kPoseSize * p.bones[j]), p.x);
      }
      const Eigen::Vector3d c = Apply(g, y);
      matches.vertex.push_back(static_cast<int>(i));
      matches.pixel.emplace_back(k[0] * c.x() / c.z() + k[2], k[1] * c.y() / c.z() + k[3]);
    }
  }
};

TEST(BoneRegistration, FrameFitRecoversAKnownArticulationFromExactMatches) {
  const ExactMatchCase scene;
  const int B = ExactMatchCase::B;
  const std::vector<double>& bones = scene.bar.bones;
  const RegistrationProxy& proxy = scene.proxy;
  ASSERT_EQ(proxy.points.size(), 300u);
  ASSERT_EQ(proxy.pairs.size(), 1u);
  const std::vector<double>& truth = scene.truth;
  const Pose& g = scene.g;
  const Eigen::Vector4d& k = scene.k;
  const FrameMatches& matches = scene.matches;
  BoneRegistrationConfig config;
  config.smooth_weight = 0.0;  // exact matches need no prior; the joint
  config.rest_weight = 0.0;    // term is not exact for a moved joint
  config.joint_weight = 0.0;
  config.iterations = 50;
  std::vector<double> bones_t = IdentityBoneTransforms(B);
  const FrameRegistration fit = RegisterFrameBones(
      FrameInputs(proxy, matches, B, bones.data(), g, k), config, bones_t.data());
  EXPECT_GT(fit.median_match_px_before, 5.0);
  EXPECT_LT(fit.median_match_px_after, 0.01);
  EXPECT_LT(fit.final_cost, 1e-6 * fit.initial_cost);
  // Bone 1's rotation (well seen: its points move by tens of pixels).
  const Eigen::Quaterniond q(bones_t[kPoseSize], bones_t[kPoseSize + 1], bones_t[kPoseSize + 2],
                             bones_t[kPoseSize + 3]);
  const Eigen::Quaterniond q_true(truth[kPoseSize], truth[kPoseSize + 1], truth[kPoseSize + 2],
                                  truth[kPoseSize + 3]);
  EXPECT_LT(q.angularDistance(q_true), 0.1 * kDeg);

  // With priors and no matches the fit stays at the rest pose.
  std::vector<double> rest = IdentityBoneTransforms(B);
  const FrameMatches no_matches;
  const FrameRegistration none = RegisterFrameBones(
      FrameInputs(proxy, no_matches, B, bones.data(), g, k), BoneRegistrationConfig{}, rest.data());
  EXPECT_EQ(none.final_cost, 0.0);
  for (int b = 0; b < B; ++b) {
    EXPECT_NEAR(rest[kPoseSize * b], 1.0, 1e-12);
    for (int i = 1; i < kPoseSize; ++i) EXPECT_NEAR(rest[kPoseSize * b + i], 0.0, 1e-12);
  }
}

// With an alternative start the fit starts from the cheaper of the two
// (bones_t's own value on a tie); the report counts the frames that kept
// their own.
TEST(BoneRegistration, FrameFitStartsFromTheCheaperOfTwoStarts) {
  const ExactMatchCase scene;
  const int B = ExactMatchCase::B;
  BoneRegistrationConfig config;
  config.smooth_weight = 0.0;  // as above: the truth costs nothing
  config.rest_weight = 0.0;
  config.joint_weight = 0.0;
  config.iterations = 1;  // the start shows in the fit's first cost
  const std::vector<double> rest = IdentityBoneTransforms(B);
  auto fit = [&](const std::vector<double>& own, const std::vector<double>* alternative) {
    std::vector<double> bones_t = own;
    FrameRegistrationInputs in =
        FrameInputs(scene.proxy, scene.matches, B, scene.bar.bones.data(), scene.g, scene.k);
    in.alternative_start = alternative != nullptr ? alternative->data() : nullptr;
    return RegisterFrameBones(in, config, bones_t.data());
  };
  const FrameRegistration from_rest = fit(rest, nullptr);
  const FrameRegistration from_truth = fit(scene.truth, nullptr);
  ASSERT_GT(from_rest.initial_cost, 100 * from_truth.initial_cost);
  ASSERT_GT(from_rest.median_match_px_before, 5.0);

  const FrameRegistration own_wins = fit(scene.truth, &rest);
  EXPECT_FALSE(own_wins.started_from_alternative);
  EXPECT_EQ(own_wins.initial_cost, from_truth.initial_cost);
  const FrameRegistration alternative_wins = fit(rest, &scene.truth);
  EXPECT_TRUE(alternative_wins.started_from_alternative);
  EXPECT_EQ(alternative_wins.initial_cost, from_truth.initial_cost);
  EXPECT_EQ(alternative_wins.median_match_px_before, from_truth.median_match_px_before);
  const FrameRegistration tie = fit(rest, &rest);
  EXPECT_FALSE(tie.started_from_alternative);
  EXPECT_EQ(tie.initial_cost, from_rest.initial_cost);

  BoneRegistrationReport report;
  report.registered = true;
  EXPECT_EQ(report.Describe().find("own motion"), std::string::npos);
  report.own_starts = 7;
  EXPECT_NE(report.Describe().find("; 7 frames started from their own motion"), std::string::npos)
      << report.Describe();
}

// The bar with bone 1 turned by 30 deg about the view axis, seen from 3
// units; the mask is the posed bar's silhouette (every surface point drawn
// as a disc of 3 px).
struct SilhouetteCase {
  static constexpr int n = 2000;
  BarScene bar = MakeBarScene(n);
  RegistrationProxy proxy = MakeRegistrationProxy(bar.surface, bar.weights, 600, 0.15, 40, 5);
  std::vector<double> truth = IdentityBoneTransforms(BarScene::B);
  Pose g = PoseFromAngleAxis(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 3));
  Eigen::Vector4d k = Eigen::Vector4d(300, 300, 128, 128);
  cv::Mat mask = cv::Mat(256, 256, CV_8UC1, cv::Scalar(kMaskBackground));
  SilhouetteCase() {
    Eigen::Map<Pose>(truth.data() + kPoseSize) = TurnAbout(
        Eigen::Vector3d(0, 0, 30 * kDeg), Eigen::Vector3d(0.4, 0, 0), Eigen::Vector3d::Zero());
    for (int i = 0; i < n; ++i) {
      const SkinnedPoint p = MakeSkinnedPoint(bar.surface.col(i), bar.weights.col(i));
      Eigen::Vector3d y = Eigen::Vector3d::Zero();
      for (size_t j = 0; j < p.bones.size(); ++j) {
        y += p.weights[j] *
             Apply(Eigen::Map<const Pose>(truth.data() + kPoseSize * p.bones[j]), p.x);
      }
      const Eigen::Vector3d c = Apply(g, y);
      cv::circle(mask, cv::Point(k[0] * c.x() / c.z() + k[2], k[1] * c.y() / c.z() + k[3]), 3,
                 cv::Scalar(kMaskObject), cv::FILLED);
    }
  }
  // Fits from the rest pose without matches; bone 1's turn in *turn, the
  // distance (px) between its image of the bar's tip (0.9, 0, 0) and the
  // truth's in *tip_px.
  FrameRegistration Fit(const BoneRegistrationConfig& config, const FrameSilhouette* silhouette,
                        double* turn, double* tip_px, std::vector<double>* fitted = nullptr) const {
    std::vector<double> bones_t = IdentityBoneTransforms(BarScene::B);
    const FrameMatches no_matches;
    FrameRegistrationInputs in =
        FrameInputs(proxy, no_matches, BarScene::B, bar.bones.data(), g, k);
    in.silhouette = silhouette;
    const FrameRegistration fit = RegisterFrameBones(in, config, bones_t.data());
    *turn = RotationAngleBetween(bones_t.data() + kPoseSize, PoseIdentity().data());
    auto tip = [&](const double* pose) {
      const Eigen::Vector3d c =
          Apply(g, Apply(Eigen::Map<const Pose>(pose), Eigen::Vector3d(0.9, 0, 0)));
      return Eigen::Vector2d(k[0] * c.x() / c.z() + k[2], k[1] * c.y() / c.z() + k[3]);
    };
    *tip_px = (tip(bones_t.data() + kPoseSize) - tip(truth.data() + kPoseSize)).norm();
    if (fitted != nullptr) *fitted = bones_t;
    return fit;
  }
};

BoneRegistrationConfig SilhouetteOnlyConfig() {
  BoneRegistrationConfig config;
  config.smooth_weight = 0.0;
  config.rest_weight = 0.0;
  config.joint_weight = 0.0;
  config.iterations = 50;
  return config;
}

TEST(BoneRegistration, MaskTermPullsABoneNoMatchSeesIntoTheSilhouette) {
  const SilhouetteCase scene;
  FrameSilhouette silhouette;
  silhouette.outside_distance = MaskOutsideDistance(scene.mask);
  BoneRegistrationConfig config = SilhouetteOnlyConfig();
  config.mask_weight = 1.0;
  config.mask_points = 300;
  // No matches at all: the silhouette alone brings every mask point inside
  // (cost 1.42 -> 1e-5 when written). It only asks the points to fall
  // inside, not to cover the mask, so the bone may also fold toward the
  // camera (here it turns by ~45 deg, partly about the depth axis, against
  // the true 30 deg about the view axis): the bone moves, not necessarily to
  // the truth.
  double turn, tip_px;
  std::vector<double> bones_t;
  const FrameRegistration fit = scene.Fit(config, &silhouette, &turn, &tip_px, &bones_t);
  EXPECT_GT(fit.initial_cost, 1.0);
  EXPECT_LT(fit.final_cost, 1e-3 * fit.initial_cost);
  EXPECT_GT(turn, 20 * kDeg);
  EXPECT_LT(RotationAngleBetween(bones_t.data(), PoseIdentity().data()), turn);
  // Off (the default weight 0), or without a distance image: no change.
  config.mask_weight = 0.0;
  EXPECT_EQ(scene.Fit(config, &silhouette, &turn, &tip_px).initial_cost, 0.0);
  config.mask_weight = 1.0;
  EXPECT_EQ(scene.Fit(config, nullptr, &turn, &tip_px).initial_cost, 0.0);
}

// The coverage term ties each object pixel to the nearest projected vertex:
// with it most of the mask term's fold is undone. Measured when written
// (tip of the bar, px from the truth's): mask alone 28.0, mask + coverage
// 7.5 (10 rounds of 2 iterations; 3 rounds: 13.7, 30 rounds of 20
// iterations: 5.2, the silhouette's 3 px discs leave some slack), coverage
// alone 15.9.
TEST(BoneRegistration, CoverageTermUnfoldsWhatContainmentAllows) {
  const SilhouetteCase scene;
  FrameSilhouette silhouette;
  silhouette.outside_distance = MaskOutsideDistance(scene.mask);
  silhouette.object_pixels = SampleObjectPixels(scene.mask, 400, 3);
  ASSERT_EQ(silhouette.object_pixels.size(), 400u);
  for (const Eigen::Vector2d& q : silhouette.object_pixels) {
    ASSERT_EQ(scene.mask.at<unsigned char>(static_cast<int>(q.y()), static_cast<int>(q.x())),
              kMaskObject);
    ASSERT_EQ(q.x() - std::floor(q.x()), 0.5);  // pixel centres
    ASSERT_EQ(q.y() - std::floor(q.y()), 0.5);
  }
  BoneRegistrationConfig config = SilhouetteOnlyConfig();
  config.iterations = 20;
  config.mask_weight = 1.0;
  config.mask_points = 300;
  double turn, mask_tip_px, tip_px;
  scene.Fit(config, &silhouette, &turn, &mask_tip_px);
  EXPECT_GT(mask_tip_px, 15.0);
  config.coverage_weight = 1.0;
  const FrameRegistration fit = scene.Fit(config, &silhouette, &turn, &tip_px);
  EXPECT_GT(fit.initial_cost, 0.0);
  EXPECT_LT(tip_px, 0.4 * mask_tip_px);
  EXPECT_LT(tip_px, 10.0);
  EXPECT_GE(fit.iterations, config.coverage_rounds);  // one solve a round
  // Coverage alone (no mask term) moves the tip most of the way too.
  config.mask_weight = 0.0;
  scene.Fit(config, &silhouette, &turn, &tip_px);
  EXPECT_LT(tip_px, 0.7 * mask_tip_px);
  // Without object pixels the term is off.
  silhouette.object_pixels.clear();
  EXPECT_EQ(scene.Fit(config, &silhouette, &turn, &tip_px).initial_cost, 0.0);
}

// A rigid point cloud (a plane facing the camera, every point with its own
// feature) "rendered" into two frames: the mean-feature embedding is each
// point's own feature, and the matches find each pixel's point.
TEST(BoneRegistration, MeanFeaturesAndMatchesOnARenderedPlane) {
  const int size = 32;
  PinholeCamera camera;
  camera.width = camera.height = size;
  camera.intrinsics = Eigen::Vector4d(40, 40, size / 2.0, size / 2.0);
  ModelOptions options;
  options.num_bones = 2;
  options.field.sdf_width = 8;
  options.field.sdf_layers = 1;
  options.field.color_width = 8;
  options.field.color_layers = 1;
  options.field.embedding_width = 8;
  options.field.embedding_layers = 1;
  Model model(options, {2}, {camera});
  for (int t = 0; t < 2; ++t) {
    model.frame(0, t).root_init =
        PoseFromAngleAxis(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.02 * t, 0, 2));
  }
  // One point at the centre of every pixel of an 8 x 8 patch at depth 2,
  // seen in frame 0; frame 1 is shifted by 0.02 units = 0.4 px (same pixels).
  const int side = 8;
  Eigen::Matrix3Xd surface(3, side * side);
  auto feature = [](int i) {
    Eigen::Matrix<double, kFeatureDim, 1> f;
    for (int c = 0; c < kFeatureDim; ++c) f[c] = std::cos(0.37 * (i + 1) * (c + 1));
    return f;
  };
  Dataset data;
  data.videos.resize(1);
  data.videos[0].camera = camera;
  for (int t = 0; t < 2; ++t) {
    Frame f;
    f.index = t;
    f.mask = cv::Mat(size, size, CV_8UC1, cv::Scalar(kMaskBackground));
    f.features = cv::Mat(size, size, CV_16FC(kFeatureDim), cv::Scalar::all(0));
    data.videos[0].frames.push_back(f);
  }
  for (int i = 0; i < side * side; ++i) {
    const int px = 12 + i % side, py = 12 + i / side;
    // Pixel centre (px + 0.3, py + 0.5) at depth 2: x = (u - cx) z / fx.
    surface.col(i) =
        Eigen::Vector3d((px + 0.3 - size / 2.0) * 2 / 40.0, (py + 0.5 - size / 2.0) * 2 / 40.0, 0);
    for (Frame& f : data.videos[0].frames) {
      f.mask.at<unsigned char>(py, px) = kMaskObject;
      cv::float16_t* feat = f.features.ptr<cv::float16_t>(py) + kFeatureDim * px;
      for (int c = 0; c < kFeatureDim; ++c)
        feat[c] = cv::float16_t(static_cast<float>(feature(i)[c]));
    }
  }
  Eigen::MatrixXd weights(2, surface.cols());
  weights.row(0).setConstant(0.5);
  weights.row(1).setConstant(0.5);
  const RegistrationProxy proxy = MakeRegistrationProxy(surface, weights, 1000, 0.15, 40, 1);
  ASSERT_EQ(proxy.points.size(), surface.cols());  // fewer vertices than asked: all of them
  const Eigen::MatrixXd psi = MeanFeatureEmbedding(model, data, proxy, 0.05);
  ASSERT_EQ(psi.rows(), kFeatureDim);
  for (int i = 0; i < side * side; ++i) {
    // Half-float features: 1e-3 relative.
    EXPECT_GT(psi.col(i).dot(feature(i).normalized()), 1.0 - 1e-5) << i;
  }
  const FrameMatches m = MatchFrameFeatures(psi, data.videos[0].frames[1], 1000, 2);
  ASSERT_EQ(m.vertex.size(), static_cast<size_t>(side * side));
  for (size_t j = 0; j < m.vertex.size(); ++j) {
    const int i = m.vertex[j];
    EXPECT_EQ(m.pixel[j], Eigen::Vector2d(12 + i % side + 0.5, 12 + i / side + 0.5));
  }
  // At most `count` pixels.
  EXPECT_EQ(MatchFrameFeatures(psi, data.videos[0].frames[0], 10, 2).vertex.size(), 10u);
  // No surface vertices: no matches.
  EXPECT_TRUE(MatchFrameFeatures(Eigen::MatrixXd(kFeatureDim, 0), data.videos[0].frames[1], 10, 2)
                  .vertex.empty());
}

TEST(BoneRegistration, SaysWhyNothingWasRegistered) {
  PinholeCamera camera;
  camera.width = camera.height = 8;
  ModelOptions options;
  options.num_bones = 0;
  Model rigid(options, {1}, {camera});
  Dataset data;
  data.videos.resize(1);
  data.videos[0].frames.resize(1);
  const Eigen::AlignedBox3d box(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1));
  const BoneRegistrationReport a = RegisterBoneMotion(&rigid, data, box, {}, 1);
  EXPECT_FALSE(a.registered);
  EXPECT_NE(a.Describe().find("no bones"), std::string::npos) << a.Describe();
  options.num_bones = 2;
  Model articulated(options, {1}, {camera});
  const BoneRegistrationReport b = RegisterBoneMotion(&articulated, data, box, {}, 1);
  EXPECT_FALSE(b.registered);
  EXPECT_NE(b.Describe().find("no frame has pixel features"), std::string::npos) << b.Describe();
  // Features, but no surface in the bounds (the initial sphere is around
  // the origin): the stability suite's 90-deg root noise reached the
  // registration with an empty canonical mesh and indexed vertex -1.
  Frame& f = data.videos[0].frames[0];
  f.mask = cv::Mat(8, 8, CV_8UC1, cv::Scalar(kMaskObject));
  f.features = cv::Mat(8, 8, CV_16FC(kFeatureDim), cv::Scalar::all(0));
  const Eigen::AlignedBox3d far(Eigen::Vector3d::Constant(5), Eigen::Vector3d::Constant(6));
  const BoneRegistrationReport c = RegisterBoneMotion(&articulated, data, far, {}, 1);
  EXPECT_FALSE(c.registered);
  EXPECT_NE(c.Describe().find("no surface"), std::string::npos) << c.Describe();
}

}  // namespace
}  // namespace banmo
