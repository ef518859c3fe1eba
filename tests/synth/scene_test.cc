// Rendered scenes against independent computations from the ground-truth
// meshes: mask = projection of the GT mesh (cv::fillConvexPoly), depth = ray
// cast, flow consistency, determinism; for each built-in rig and Fox.
#include "banmo/synth/scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgproc.hpp>

#include "banmo/geometry/se3.h"
#include "banmo/io/dataset.h"
#include "banmo/synth/features.h"
#include "banmo/synth/rasterizer.h"
#include "banmo/synth/rig_library.h"
#include "banmo/util/error.h"

namespace banmo::synth {
namespace {

namespace fs = std::filesystem;

struct Case {
  std::string rig;        // built-in name or path
  std::string animation;  // empty: the first
  std::string label;
};

std::ostream& operator<<(std::ostream& os, const Case& c) { return os << c.label; }

const std::string kFox = BANMO_SHARED_DIR "/data/gltf/Fox/Fox.glb";

SynthOptions SmallOptions(const Case& c) {
  SynthOptions o;
  o.num_videos = 2;
  o.frames_per_video = 5;
  o.image_size = 96;
  o.flow_gaps = {1, 2};
  o.animation = c.animation;
  o.seed = 7;
  return o;
}

// Projection of the GT mesh, computed independently of the rasteriser with
// OpenCV: a pixel belongs to it when its centre (i + 0.5, j + 0.5) is inside
// or on a projected triangle (cv::pointPolygonTest >= 0), the sampling rule
// the rasteriser documents. `fill` also returns cv::fillConvexPoly's mask,
// which marks every pixel an edge passes through (so it is a superset).
cv::Mat ProjectedMask(const PinholeCamera& camera, const TriangleMesh& mesh, cv::Mat* fill) {
  cv::Mat mask = cv::Mat::zeros(camera.height, camera.width, CV_8UC1);
  *fill = cv::Mat::zeros(camera.height, camera.width, CV_8UC1);
  constexpr int kShift = 8;
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    std::vector<cv::Point2f> tri(3);
    cv::Point pts[3];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.vertices.col(mesh.faces(k, f));
      const double u = camera.intrinsics[0] * p.x() / p.z() + camera.intrinsics[2];
      const double v = camera.intrinsics[1] * p.y() / p.z() + camera.intrinsics[3];
      tri[k] = cv::Point2f(static_cast<float>(u), static_cast<float>(v));
      // OpenCV's pixel centres are integers, ours at i + 0.5: hence -0.5.
      pts[k] = cv::Point(static_cast<int>(std::lround((u - 0.5) * (1 << kShift))),
                         static_cast<int>(std::lround((v - 0.5) * (1 << kShift))));
    }
    cv::fillConvexPoly(*fill, pts, 3, cv::Scalar(255), cv::LINE_8, kShift);
    const cv::Rect box = cv::boundingRect(tri) & cv::Rect(0, 0, camera.width, camera.height);
    for (int y = box.y; y < box.y + box.height; ++y) {
      for (int x = box.x; x < box.x + box.width; ++x) {
        if (mask.at<unsigned char>(y, x)) continue;
        if (cv::pointPolygonTest(tri, cv::Point2f(x + 0.5f, y + 0.5f), false) >= 0) {
          mask.at<unsigned char>(y, x) = 255;
        }
      }
    }
  }
  return mask;
}

// Nearest ray hit (Moller-Trumbore) along the ray through pixel centre (x, y);
// returns the camera z of the hit or 0 when the ray misses.
double RayCastDepth(const PinholeCamera& camera, const TriangleMesh& mesh, int x, int y) {
  const double uv[2] = {x + 0.5, y + 0.5};
  double d[3];
  PixelToRayDirection(camera.intrinsics.data(), uv, d);
  const Eigen::Vector3d dir(d[0], d[1], d[2]);
  double best = std::numeric_limits<double>::infinity();
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d e1 = mesh.vertices.col(mesh.faces(1, f)) - a;
    const Eigen::Vector3d e2 = mesh.vertices.col(mesh.faces(2, f)) - a;
    const Eigen::Vector3d p = dir.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-14) continue;
    const Eigen::Vector3d s = -a;  // ray origin is the camera centre
    const double bu = s.dot(p) / det;
    if (bu < 0 || bu > 1) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double bv = dir.dot(q) / det;
    if (bv < 0 || bu + bv > 1) continue;
    const double t = e2.dot(q) / det;  // z of the hit, since dir.z = 1
    if (t > 0) best = std::min(best, t);
  }
  return std::isfinite(best) ? best : 0.0;
}

class SceneTest : public testing::TestWithParam<Case> {};

TEST_P(SceneTest, MaskDepthFlowMatchTheGroundTruthMesh) {
  const Case& c = GetParam();
  const Rig rig = LoadRig(c.rig);
  SynthOptions o = SmallOptions(c);
  o.feature_noise = 0;  // noise-free features to check the flow with
  const SynthScene scene = RenderSyntheticScene(rig, o);
  ASSERT_EQ(scene.dataset.videos.size(), 2u);
  const PinholeCamera& cam = scene.dataset.videos[0].camera;
  double worst_iou = 1, worst_fill_iou = 1;
  std::vector<double> flow_errors, shifted_errors;
  int checked_depths = 0;
  for (size_t v = 0; v < scene.dataset.videos.size(); ++v) {
    const Video& video = scene.dataset.videos[v];
    for (size_t f = 0; f < video.frames.size(); ++f) {
      const Frame& frame = video.frames[f];
      const TriangleMesh& mesh = scene.gt_meshes[v][f];
      // Mask vs the independent projection of the GT mesh.
      cv::Mat fill;
      const cv::Mat proj = ProjectedMask(cam, mesh, &fill);
      const int inter = cv::countNonZero(proj & frame.mask);
      const int uni = cv::countNonZero(proj | frame.mask);
      ASSERT_GT(uni, 100) << "object too small in video " << v << " frame " << f;
      worst_iou = std::min(worst_iou, static_cast<double>(inter) / uni);
      // The rendered mask lies inside fillConvexPoly's superset.
      EXPECT_EQ(cv::countNonZero(frame.mask & ~fill), 0);
      worst_fill_iou =
          std::min(worst_fill_iou, static_cast<double>(cv::countNonZero(fill & frame.mask)) /
                                       cv::countNonZero(fill | frame.mask));
      // Depth vs ray casting at every 5th pixel (in and out of the mask).
      for (int y = 2; y < cam.height; y += 5) {
        for (int x = 2; x < cam.width; x += 5) {
          const double z = RayCastDepth(cam, mesh, x, y);
          const float d = frame.depth.at<float>(y, x);
          if (z == 0 || d == 0) {
            // Pixel centres exactly on an edge may go either way; elsewhere
            // both agree on background (checked through the IoU too).
            continue;
          }
          // 1e-5 relative: float32 storage of the depth (~6e-8) and rounding
          // of the barycentrics.
          EXPECT_NEAR(d, z, 1e-5 * z) << "video " << v << " frame " << f << " at " << x << "," << y;
          ++checked_depths;
        }
      }
      // Flow consistency: pixel p of frame t and the point p + flow of frame
      // t + gap see the same rest-pose point, so their noise-free features
      // agree.
      for (const FlowField& ff : frame.flows) {
        const Frame& other = video.frames[f + ff.gap];
        cv::Mat flow32, feat_t, feat_o;
        ff.flow.convertTo(flow32, CV_32F);
        frame.features.convertTo(feat_t, CV_32F);
        other.features.convertTo(feat_o, CV_32F);
        for (int y = 0; y < cam.height; ++y) {
          for (int x = 0; x < cam.width; ++x) {
            if (!ff.valid.at<unsigned char>(y, x)) continue;
            ASSERT_EQ(frame.mask.at<unsigned char>(y, x), kMaskObject);
            const cv::Vec2f fl = flow32.at<cv::Vec2f>(y, x);
            // Feature distance between pixel (x, y) of frame t and the
            // bilinear lookup at pixel position (u, v) of frame t + gap, or
            // -1 where the lookup is not on a continuous surface: all 4
            // neighbours object with depths within 2 % (no occlusion edge
            // between them, across which interpolation mixes two surfaces).
            auto warp_error = [&](float u, float v) -> double {
              const float qx = u - 0.5f, qy = v - 0.5f;  // to pixel-index coordinates
              const int x0 = static_cast<int>(std::floor(qx)),
                        y0 = static_cast<int>(std::floor(qy));
              if (x0 < 0 || y0 < 0 || x0 + 1 >= cam.width || y0 + 1 >= cam.height) return -1;
              float dmin = std::numeric_limits<float>::infinity(), dmax = 0;
              for (int k = 0; k < 4; ++k) {
                const float d = other.depth.at<float>(y0 + k / 2, x0 + k % 2);
                dmin = std::min(dmin, d);
                dmax = std::max(dmax, d);
              }
              if (dmin == 0 || dmax > 1.02f * dmin) return -1;
              const float ax = qx - x0, ay = qy - y0;
              double err2 = 0;
              for (int ch = 0; ch < kFeatureDim; ++ch) {
                auto at = [&](int yy, int xx) {
                  return feat_o.ptr<float>(yy)[xx * kFeatureDim + ch];
                };
                const float warped = (1 - ay) * ((1 - ax) * at(y0, x0) + ax * at(y0, x0 + 1)) +
                                     ay * ((1 - ax) * at(y0 + 1, x0) + ax * at(y0 + 1, x0 + 1));
                const float mine = feat_t.ptr<float>(y)[x * kFeatureDim + ch];
                err2 += (warped - mine) * (warped - mine);
              }
              return std::sqrt(err2);
            };
            const float u = x + 0.5f + fl[0], v = y + 0.5f + fl[1];
            const double e = warp_error(u, v);
            if (e < 0) continue;
            flow_errors.push_back(e);
            // The same with the flow off by one pixel, for scale.
            const double e_off = warp_error(u + 1, v);
            if (e_off >= 0) shifted_errors.push_back(e_off);
          }
        }
      }
    }
  }
  EXPECT_GE(worst_iou, 0.99) << c.label;
  EXPECT_GT(checked_depths, 100);
  ASSERT_GT(flow_errors.size(), 1000u);
  std::sort(flow_errors.begin(), flow_errors.end());
  const double median = flow_errors[flow_errors.size() / 2];
  const double p95 = flow_errors[flow_errors.size() * 95 / 100];
  const double p99 = flow_errors[flow_errors.size() * 99 / 100];
  std::sort(shifted_errors.begin(), shifted_errors.end());
  const double shifted_median = shifted_errors[shifted_errors.size() / 2];
  // Tolerances (unit-length 16-d features): measured medians are 0.003 and
  // 95th percentiles 0.012-0.027 (bilinear interpolation error over creases
  // and thin parts, half-float storage), while the same flow off by one pixel
  // gives a median ~10x larger. So: median < 0.01, p95 < 0.05, and the
  // one-pixel-off median at least 4x the true one.
  EXPECT_LT(median, 0.01) << c.label;
  EXPECT_LT(p95, 0.05) << c.label;
  EXPECT_GT(shifted_median, 4 * median) << c.label;
  std::printf(
      "[%s] worst mask IoU %.4f (fillConvexPoly %.4f), depth checks %d, flow feature error median "
      "%.4f p95 %.4f p99 %.4f over %zu px (flow off by 1 px: median %.4f)\n",
      c.label.c_str(), worst_iou, worst_fill_iou, checked_depths, median, p95, p99,
      flow_errors.size(), shifted_median);
}

std::vector<char> ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}

TEST_P(SceneTest, SameSeedGivesTheSameBytes) {
  const Case& c = GetParam();
  const Rig rig = LoadRig(c.rig);
  SynthOptions o = SmallOptions(c);
  o.frames_per_video = 3;
  o.pose_noise_deg = 20;
  const std::string base = testing::TempDir() + "/synth_same_seed_" + std::to_string(::getpid());
  const std::string dir_a = base + "_a", dir_b = base + "_b";
  fs::remove_all(dir_a);
  fs::remove_all(dir_b);
  {
    const SynthScene a = RenderSyntheticScene(rig, o);
    WriteDataset(a.dataset, dir_a, &a.gt_meshes);
  }
  {
    const SynthScene b = RenderSyntheticScene(rig, o);
    WriteDataset(b.dataset, dir_b, &b.gt_meshes);
  }
  int files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(dir_a)) {
    if (!entry.is_regular_file()) continue;
    const fs::path rel = fs::relative(entry.path(), dir_a);
    ASSERT_TRUE(fs::exists(fs::path(dir_b) / rel)) << rel;
    EXPECT_TRUE(ReadBytes(entry.path()) == ReadBytes(fs::path(dir_b) / rel)) << rel;
    ++files;
  }
  EXPECT_GT(files, 20);
  // The written dataset is accepted by the validating loader.
  const Dataset loaded = LoadDataset(dir_a);
  EXPECT_EQ(loaded.NumFrames(), 6);
  // A different seed changes the scene.
  o.seed += 1;
  const SynthScene d = RenderSyntheticScene(rig, o);
  const Pose& p_a = loaded.videos[0].frames[0].root_pose_gt.value();
  const Pose& p_d = d.dataset.videos[0].frames[0].root_pose_gt.value();
  EXPECT_GT((p_a - p_d).norm(), 1e-3);
  fs::remove_all(dir_a);
  fs::remove_all(dir_b);
}

INSTANTIATE_TEST_SUITE_P(Rigs, SceneTest,
                         testing::Values(Case{"quadruped", "", "quadruped"},
                                         Case{"bird", "", "bird"}, Case{"hand", "", "hand"},
                                         Case{kFox, "Survey", "FoxSurvey"},
                                         Case{kFox, "Walk", "FoxWalk"},
                                         Case{kFox, "Run", "FoxRun"}),
                         [](const testing::TestParamInfo<Case>& info) { return info.param.label; });

TEST(ScenePlan, NormalisationPoseNoiseAndCameraDistance) {
  const Rig rig = LoadRig("quadruped");
  SynthOptions o;
  o.num_videos = 3;
  o.frames_per_video = 4;
  o.pose_noise_deg = 20;
  const ScenePlan plan = PlanScene(rig, o);
  // Rest mesh in root coordinates: largest half-extent 1, centred.
  Eigen::Matrix3Xd rest = rig.rest_vertices;
  rest.colwise() -= plan.normalization.center;
  rest *= plan.normalization.scale;
  const Eigen::Vector3d lo = rest.rowwise().minCoeff(), hi = rest.rowwise().maxCoeff();
  EXPECT_NEAR(0.5 * (hi - lo).maxCoeff(), 1.0, 1e-12);
  EXPECT_LT((lo + hi).norm(), 1e-12);
  for (const auto& video : plan.frames) {
    for (const auto& fp : video) {
      // The rough pose is the GT rotated by exactly 20 degrees (1e-9 rad).
      EXPECT_NEAR(
          RotationAngleBetween(fp.camera_from_root_gt.data(), fp.camera_from_root_init.data()),
          20 * M_PI / 180, 1e-9);
      // The root origin (object centre) is ~3 units in front of the camera
      // (distance 3 +- 5 % jitter, plus the posed-centre offset and drift).
      const double z = fp.camera_from_root_gt[kPoseT + 2];
      EXPECT_GT(z, 2.5);
      EXPECT_LT(z, 3.5);
    }
  }
}

// One video of 3 frames, 32 px, rough poses 10 deg off: the scene the
// transformed-scene tests below compare against.
SynthOptions SmallNoisyScene() {
  SynthOptions o;
  o.num_videos = 1;
  o.frames_per_video = 3;
  o.image_size = 32;
  o.flow_gaps = {1};
  o.pose_noise_deg = 10;
  return o;
}

// object_scale: the same images, every length times s (exact up to the
// rounding of one multiplication: 1e-12 relative).
TEST(Scene, ObjectScaleScalesLengthsAndKeepsImages) {
  const Rig rig = LoadRig("quadruped");
  SynthOptions o = SmallNoisyScene();
  const SynthScene ref = RenderSyntheticScene(rig, o);
  for (double s : {0.01, 100.0}) {
    o.object_scale = s;
    const SynthScene scaled = RenderSyntheticScene(rig, o);
    for (int f = 0; f < o.frames_per_video; ++f) {
      const Frame& a = ref.dataset.videos[0].frames[f];
      const Frame& b = scaled.dataset.videos[0].frames[f];
      EXPECT_EQ(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 0);
      EXPECT_EQ(cv::norm(a.mask, b.mask, cv::NORM_INF), 0);
      EXPECT_LE(cv::norm(a.depth * s, b.depth, cv::NORM_INF), 1e-5 * s);  // float32 depth
      for (int k = 0; k < kPoseSize; ++k) {
        const double fs = k >= kPoseT ? s : 1.0;
        EXPECT_NEAR(fs * a.root_pose_gt.value()[k], b.root_pose_gt.value()[k], 1e-12 * s * 10);
        EXPECT_NEAR(fs * a.root_pose_init[k], b.root_pose_init[k], 1e-12 * s * 10);
      }
      EXPECT_LE((s * ref.gt_meshes[0][f].vertices - scaled.gt_meshes[0][f].vertices)
                    .cwiseAbs()
                    .maxCoeff(),
                1e-12 * s * 10);
    }
  }
  o.object_scale = 0;
  EXPECT_THROW(o.Check(), InputError);
}

// root_offset: the same images, depth and ground-truth meshes; only the root
// frame moves, so every written root pose (ground truth and rough) becomes
// camera_from_root * T(-s offset) (s = object_scale): the same rotation, the
// translation t - s R offset (1e-12: one product and sum of O(1) numbers).
TEST(Scene, RootOffsetMovesTheRootFrameOnly) {
  const Rig rig = LoadRig("quadruped");
  SynthOptions o = SmallNoisyScene();
  o.object_scale = 2;
  const SynthScene ref = RenderSyntheticScene(rig, o);
  o.root_offset = Eigen::Vector3d(0.3, -0.9, 0.5);
  const SynthScene moved = RenderSyntheticScene(rig, o);
  const Eigen::Vector3d shift = o.object_scale * o.root_offset;
  for (int f = 0; f < o.frames_per_video; ++f) {
    const Frame& a = ref.dataset.videos[0].frames[f];
    const Frame& b = moved.dataset.videos[0].frames[f];
    EXPECT_EQ(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a.mask, b.mask, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0);
    EXPECT_EQ(ref.gt_meshes[0][f].vertices, moved.gt_meshes[0][f].vertices);
    for (const auto& [pa, pb] : {std::make_pair(a.root_pose_gt.value(), b.root_pose_gt.value()),
                                 std::make_pair(a.root_pose_init, b.root_pose_init)}) {
      const Eigen::Isometry3d ia = IsometryFromPose(pa.data());
      const Eigen::Isometry3d ib = IsometryFromPose(pb.data());
      EXPECT_LE((ia.linear() - ib.linear()).cwiseAbs().maxCoeff(), 1e-12);
      EXPECT_LE((ia.translation() - ia.linear() * shift - ib.translation()).norm(), 1e-12);
      // A root point seen by the old frame at x is seen by the new one at
      // x + shift: the same camera point.
      const Eigen::Vector3d x(0.2, 0.1, -0.4);
      EXPECT_LE((ia * x - ib * (x + shift)).norm(), 1e-12);
    }
  }
  o.root_offset = Eigen::Vector3d(0, 200, 0);
  EXPECT_THROW(o.Check(), InputError);
  o.root_offset = Eigen::Vector3d(0, std::nan(""), 0);
  EXPECT_THROW(o.Check(), InputError);
}

TEST(ScenePlan, BadOptionsAndAnimationNamesAreInputErrors) {
  const Rig rig = LoadRig("bird");
  SynthOptions o;
  o.animation = "moonwalk";
  try {
    PlanScene(rig, o);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("moonwalk"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("flap"), std::string::npos);
  }
  o = SynthOptions();
  o.flow_gaps = {1, 1};
  EXPECT_THROW(o.Check(), InputError);
  o = SynthOptions();
  o.frames_per_video = 1;
  EXPECT_THROW(o.Check(), InputError);
  o = SynthOptions();
  o.pose_noise_deg = -1;
  EXPECT_THROW(o.Check(), InputError);
}

TEST(Rasterizer, PerspectiveCorrectBarycentricsAndDepth) {
  PinholeCamera cam;
  cam.width = cam.height = 64;
  cam.intrinsics = Eigen::Vector4d(50, 50, 32, 32);
  // A slanted triangle (depth 2 to 4) covering the image centre.
  Eigen::Matrix3Xd v(3, 3);
  v.col(0) = Eigen::Vector3d(-1, -1, 2);
  v.col(1) = Eigen::Vector3d(2, -0.5, 4);
  v.col(2) = Eigen::Vector3d(-0.5, 2, 3);
  Eigen::Matrix3Xi f(3, 1);
  f << 0, 1, 2;
  const RasterBuffers r = Rasterize(cam, v, f);
  int covered = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      if (r.face.at<int>(y, x) < 0) continue;
      ++covered;
      const Eigen::Vector3d b = r.Barycentrics(x, y);
      const Eigen::Vector3d p = b[0] * v.col(0) + b[1] * v.col(1) + b[2] * v.col(2);
      // The interpolated 3D point projects to the pixel centre and has the
      // stored depth (1e-5: float32 storage).
      double uv[2];
      ProjectPoint(cam.intrinsics.data(), p.data(), uv);
      EXPECT_NEAR(uv[0], x + 0.5, 1e-4);
      EXPECT_NEAR(uv[1], y + 0.5, 1e-4);
      EXPECT_NEAR(r.depth.at<float>(y, x), p.z(), 1e-5 * p.z());
    }
  }
  EXPECT_GT(covered, 300);
}

TEST(Rasterizer, NearerTriangleWins) {
  PinholeCamera cam;
  cam.width = cam.height = 16;
  cam.intrinsics = Eigen::Vector4d(10, 10, 8, 8);
  Eigen::Matrix3Xd v(3, 6);
  v << -5, 5, 0, -5, 5, 0,   //
      -5, -5, 5, -5, -5, 5,  //
      3, 3, 3, 2, 2, 2;
  Eigen::Matrix3Xi f(3, 2);
  f << 0, 3, 1, 4, 2, 5;
  const RasterBuffers r = Rasterize(cam, v, f);
  EXPECT_EQ(r.face.at<int>(8, 8), 1);
  EXPECT_FLOAT_EQ(r.depth.at<float>(8, 8), 2.0f);
}

TEST(FeatureEmbedding, UnitLengthSmoothAndFixed) {
  const FeatureEmbedding e1, e2;
  const Eigen::Vector3d x(0.3, -0.2, 0.5);
  EXPECT_NEAR(e1(x).norm(), 1.0, 1e-12);
  EXPECT_EQ(e1(x), e2(x));  // fixed seed: the same embedding every time
  // Smooth: a 0.01 step changes the feature by at most ~0.01 * 2 * frequency * sqrt(16).
  EXPECT_LT((e1(x) - e1(x + Eigen::Vector3d(0.01, 0, 0))).norm(), 0.01 * 2 * kFeatureFrequency * 4);
  // Distinct: points far apart have clearly different features.
  EXPECT_GT((e1(x) - e1(-x)).norm(), 0.3);
}

}  // namespace
}  // namespace banmo::synth
