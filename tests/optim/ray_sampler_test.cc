// RaySampler (optim/ray_sampler.h): what a minibatch's rays are made of.
// The solver tests use it indirectly; these hold its contract directly.
#include "banmo/optim/ray_sampler.h"

#include <gtest/gtest.h>

#include <map>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "banmo/model/make_model.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

const Eigen::AlignedBox3d kBounds(Eigen::Vector3d::Constant(-1.2), Eigen::Vector3d::Constant(1.2));

// The tiny quadruped dataset, a model for it and a sampler over it.
class RaySamplerTest : public ::testing::Test {
 protected:
  const Dataset& data = testing::TinyQuadrupedDataset();
  const std::unique_ptr<Model> model =
      MakeModelForDataset(data, testing::TinySolverConfig(StepRule::kAdam, 1).model);
  RaySampler sampler{data};
};

TEST_F(RaySamplerTest, RaysCarryTheirDataAndSortedSamples) {
  SamplingConfig sampling;
  sampling.flow_gaps = {1, 2};
  std::mt19937 rng(5);
  const std::vector<Ray> rays = sampler.Sample(200, 12, sampling, *model, kBounds, &rng);
  ASSERT_EQ(rays.size(), 200u);
  int object = 0;
  for (const Ray& ray : rays) {
    ASSERT_GE(ray.video, 0);
    ASSERT_LT(ray.video, static_cast<int>(data.videos.size()));
    const Video& video = data.videos[ray.video];
    ASSERT_GE(ray.frame, 0);
    ASSERT_LT(ray.frame, static_cast<int>(video.frames.size()));
    EXPECT_EQ(ray.NumSamples(), 12);
    for (int i = 1; i < ray.NumSamples(); ++i) {
      EXPECT_GT(ray.samples.depths[i], ray.samples.depths[i - 1]);
    }
    for (double d : ray.samples.deltas) EXPECT_GT(d, 0.0);
    if (ray.has_flow) {
      EXPECT_NE(ray.partner_frame, ray.frame);
      EXPECT_LE(std::abs(ray.partner_frame - ray.frame), 2);
    }
    if (ray.has_feature) {
      EXPECT_GE(ray.mask, 0.5);  // features only on the object
    }
    object += ray.mask >= 0.5;
  }
  // foreground_fraction 0.5 of the rays come from inside the mask, and some
  // of the uniform ones land there too.
  EXPECT_GE(object, 100);
}

// clip_to_box: every ray's samples lie in its part inside the widened box
// (ClipDepthsToBox), which for object rays is shorter than the frame's
// near-far range.
TEST_F(RaySamplerTest, ClipToBoxKeepsTheSamplesInTheWidenedBox) {
  SamplingConfig sampling;
  sampling.clip_to_box = true;
  sampling.clip_margin = 0.05;
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-0.8, -0.5, -0.4), Eigen::Vector3d(0.8, 0.5, 0.4));
  std::mt19937 rng(3);
  const std::vector<Ray> rays = sampler.Sample(100, 12, sampling, *model, box, &rng);
  int clipped = 0;
  for (const Ray& ray : rays) {
    double near = 0, far = 0;
    const Pose pose = model->RootPose(ray.video, ray.frame);
    NearFarPlanes(pose, box, sampling.near_far_margin, &near, &far);
    const double plane_range = far - near;
    const bool hit = ClipDepthsToBox(pose, box, sampling.clip_margin,
                                     model->video(ray.video).intrinsics, ray.uv, &near, &far);
    clipped += hit && far - near < plane_range;
    const double last_end =
        ray.samples.depths.back() + ray.samples.deltas.back() / ray.samples.dir_norm;
    EXPECT_GE(ray.samples.depths.front(), near - 1e-12);
    EXPECT_LE(last_end, far + 1e-9);
  }
  EXPECT_GE(clipped, 50);  // at least the object rays
}

TEST_F(RaySamplerTest, SameSeedSameRays) {
  SamplingConfig sampling;
  std::mt19937 a(9), b(9);
  const std::vector<Ray> ra = sampler.Sample(50, 8, sampling, *model, kBounds, &a);
  const std::vector<Ray> rb = sampler.Sample(50, 8, sampling, *model, kBounds, &b);
  ASSERT_EQ(ra.size(), rb.size());
  for (size_t r = 0; r < ra.size(); ++r) {
    EXPECT_EQ(ra[r].uv, rb[r].uv);
    EXPECT_EQ(ra[r].samples.depths, rb[r].samples.depths);
    EXPECT_EQ(ra[r].partner_frame, rb[r].partner_frame);
  }
}

// sampling.frames_per_batch: a batch's rays come from that many distinct
// frames, evenly; different batches draw different frames.
TEST_F(RaySamplerTest, FramesPerBatchSpreadsTheRaysOverThatManyFrames) {
  const int usable = static_cast<int>(sampler.UsableFrames().size());
  ASSERT_GT(usable, 3);
  SamplingConfig sampling;
  sampling.frames_per_batch = 3;
  std::mt19937 rng(4);
  std::set<std::pair<int, int>> seen;
  for (int batch = 0; batch < 10; ++batch) {
    const std::vector<Ray> rays = sampler.Sample(31, 4, sampling, *model, kBounds, &rng);
    ASSERT_EQ(rays.size(), 31u);
    std::map<std::pair<int, int>, int> count;
    for (const Ray& r : rays) ++count[{r.video, r.frame}];
    ASSERT_EQ(count.size(), 3u);
    for (const auto& [frame, n] : count) {
      EXPECT_TRUE(n == 10 || n == 11) << n;  // 31 = 11 + 10 + 10
      seen.insert(frame);
    }
  }
  EXPECT_GT(seen.size(), 3u);  // not the same three frames every batch
  // As many frames as the dataset has, or more: every ray draws its frame.
  sampling.frames_per_batch = usable;
  std::mt19937 a(8), b(8);
  SamplingConfig any;
  const std::vector<Ray> ra = sampler.Sample(40, 4, sampling, *model, kBounds, &a);
  const std::vector<Ray> rb = sampler.Sample(40, 4, any, *model, kBounds, &b);
  for (size_t r = 0; r < ra.size(); ++r) EXPECT_EQ(ra[r].uv, rb[r].uv);
}

// sampling.unbiased_silhouette: over many draws of one frame, the
// importance-weighted mean of any pixel quantity is its mean over all the
// frame's pixels (here the object indicator, the known-mask indicator and
// the edge-band indicator), while the unweighted mean favours the pixels
// the sampler draws more often; with and without the edge band.
TEST_F(RaySamplerTest, UnbiasedSilhouetteWeightsUndoTheObjectPreference) {
  const auto [v, t] = sampler.UsableFrames().front();
  const cv::Mat& mask = data.videos[v].frames[t].mask;
  const double n = static_cast<double>(mask.total());
  const double object_share = cv::countNonZero(mask == kMaskObject) / n;
  const double known_share = object_share + cv::countNonZero(mask == kMaskBackground) / n;
  std::set<int> band(sampler.BoundaryPixels(v, t).begin(), sampler.BoundaryPixels(v, t).end());
  const double band_share = band.size() / n;
  ASSERT_GT(object_share, 0.01);
  ASSERT_LT(object_share, 0.5);
  ASSERT_GT(band_share, 0.01);
  ASSERT_LT(band_share, 0.5);
  for (const double boundary_fraction : {0.0, 0.2}) {
    SCOPED_TRACE(boundary_fraction);
    SamplingConfig sampling;
    sampling.unbiased_silhouette = true;
    sampling.foreground_fraction = 0.6;
    sampling.boundary_fraction = boundary_fraction;
    std::mt19937 rng(11);
    const int count = 40000;
    const std::vector<Ray> rays =
        sampler.SampleFrame(v, t, count, 2, sampling, *model, kBounds, &rng);
    double weighted_object = 0, weighted_known = 0, weighted_band = 0;
    double unweighted_object = 0, unweighted_band = 0;
    for (const Ray& r : rays) {
      const int x = static_cast<int>(r.uv.x()), y = static_cast<int>(r.uv.y());
      const bool in_band = band.count(y * mask.cols + x) > 0;
      unweighted_band += in_band;
      if (r.mask < 0) {
        EXPECT_EQ(r.silhouette_weight, 1.0);  // no silhouette term
        continue;
      }
      EXPECT_EQ(r.silhouette_weight, sampler.PixelWeight(v, t, x, y, sampling));
      weighted_object += r.silhouette_weight * (r.mask >= 0.5);
      weighted_known += r.silhouette_weight;
      weighted_band += r.silhouette_weight * in_band;
      unweighted_object += r.mask >= 0.5;
    }
    // Standard errors at 40,000 draws: the known-mask indicator's is the
    // largest, as background pixels off the band (most of the frame) weigh
    // 1 / (1 - f - e): 2.5 without the band (SE about 0.004), 5 with it
    // (about 0.009); the tolerances are about 4 of them.
    const double tolerance = boundary_fraction > 0 ? 0.04 : 0.015;
    EXPECT_NEAR(weighted_object / count, object_share, tolerance);
    EXPECT_NEAR(weighted_known / count, known_share, tolerance);
    EXPECT_NEAR(weighted_band / count, band_share, tolerance);
    EXPECT_GT(unweighted_object / count, object_share + 0.4);
    // The band's share of the draws: its fraction plus its share of the
    // other two parts' (object pixels in the band, uniform draws on it).
    EXPECT_GT(unweighted_band / count, boundary_fraction + band_share * 0.1 - 0.02);
  }
  // Off: every weight is 1.
  SamplingConfig sampling;
  std::mt19937 rng(12);
  for (const Ray& r : sampler.SampleFrame(v, t, 100, 2, sampling, *model, kBounds, &rng)) {
    EXPECT_EQ(r.silhouette_weight, 1.0);
  }
}

// crop_scale: the uniform draws stay in the mask's bounding box scaled
// about its centre, and the importance weights are then those of the crop
// (the silhouette loss estimates its mean over the crop's pixels).
TEST_F(RaySamplerTest, CropScaleKeepsTheUniformDrawsNearTheObject) {
  const auto [v, t] = sampler.UsableFrames().front();
  const cv::Mat& mask = data.videos[v].frames[t].mask;
  const cv::Rect image(0, 0, mask.cols, mask.rows);
  const cv::Mat object = mask == kMaskObject;
  const cv::Rect box = cv::boundingRect(object);
  SamplingConfig sampling;
  EXPECT_EQ(sampler.CropRect(v, t, sampling), image);  // 0: the whole image
  sampling.crop_scale = 1.5;
  const cv::Rect crop = sampler.CropRect(v, t, sampling);
  ASSERT_LT(crop.area(), image.area());  // the tiny scene's object leaves room
  EXPECT_EQ(crop & box, box);
  EXPECT_EQ(crop & image, crop);
  // Each side 1.5 times the box's, to a pixel of rounding on either end,
  // unless the image ends first.
  if (crop.x > 0 && crop.x + crop.width < image.width) {
    EXPECT_NEAR(crop.width, 1.5 * box.width, 2.0);
  }
  if (crop.y > 0 && crop.y + crop.height < image.height) {
    EXPECT_NEAR(crop.height, 1.5 * box.height, 2.0);
  }
  sampling.crop_scale = 1.0;
  EXPECT_EQ(sampler.CropRect(v, t, sampling), box);
  // The edge band reaches past the box: its pixels there are drawn by the
  // band's part alone, and weighed so.
  {
    SamplingConfig band = sampling;
    band.boundary_fraction = 0.3;
    const std::vector<int>& edge = sampler.BoundaryPixels(v, t);
    int outside = 0;
    for (const int p : edge) {
      const int x = p % mask.cols, y = p / mask.cols;
      if (box.contains(cv::Point(x, y))) continue;
      ++outside;
      EXPECT_DOUBLE_EQ(sampler.PixelWeight(v, t, x, y, band),
                       1.0 / (0.3 * box.area() / static_cast<double>(edge.size())));
    }
    EXPECT_GT(outside, 0);
  }

  sampling.crop_scale = 1.5;
  sampling.foreground_fraction = 0.5;
  sampling.unbiased_silhouette = true;
  std::mt19937 rng(5);
  const int count = 40000;
  double weighted_object = 0, weighted_known = 0;
  for (const Ray& r : sampler.SampleFrame(v, t, count, 2, sampling, *model, kBounds, &rng)) {
    const cv::Point p(static_cast<int>(r.uv.x()), static_cast<int>(r.uv.y()));
    ASSERT_TRUE(crop.contains(p)) << p;
    if (r.mask < 0) continue;
    EXPECT_EQ(r.silhouette_weight, sampler.PixelWeight(v, t, p.x, p.y, sampling));
    weighted_object += r.silhouette_weight * (r.mask >= 0.5);
    weighted_known += r.silhouette_weight;
  }
  // Unbiased over the crop: the object's and the known pixels' shares of
  // the crop (standard errors about 0.005 at 40,000 draws; 3 of them).
  const cv::Mat in_crop = mask(crop);
  const double n = static_cast<double>(crop.area());
  EXPECT_NEAR(weighted_object / count, cv::countNonZero(in_crop == kMaskObject) / n, 0.015);
  EXPECT_NEAR(
      weighted_known / count,
      (cv::countNonZero(in_crop == kMaskObject) + cv::countNonZero(in_crop == kMaskBackground)) / n,
      0.015);
}

// The edge band: every band pixel has a pixel of the other class (object /
// background) within kBoundaryBandPx (chessboard), every other known pixel
// none; all rays drawn with boundary_fraction 1 lie on it.
TEST_F(RaySamplerTest, BoundaryRaysLieOnTheMaskEdge) {
  const int r = RaySampler::kBoundaryBandPx;
  for (const auto& [v, t] : sampler.UsableFrames()) {
    const cv::Mat& mask = data.videos[v].frames[t].mask;
    const std::vector<int>& band = sampler.BoundaryPixels(v, t);
    ASSERT_FALSE(band.empty());
    const std::set<int> in_band(band.begin(), band.end());
    for (int y = 0; y < mask.rows; ++y) {
      for (int x = 0; x < mask.cols; ++x) {
        const unsigned char m = mask.at<unsigned char>(y, x);
        bool other_near = false;
        for (int dy = -r; dy <= r; ++dy) {
          for (int dx = -r; dx <= r; ++dx) {
            const int yy = y + dy, xx = x + dx;
            if (yy < 0 || yy >= mask.rows || xx < 0 || xx >= mask.cols) continue;
            const unsigned char o = mask.at<unsigned char>(yy, xx);
            other_near = other_near || (m == kMaskObject && o == kMaskBackground) ||
                         (m == kMaskBackground && o == kMaskObject);
          }
        }
        ASSERT_EQ(in_band.count(y * mask.cols + x) > 0, other_near) << x << ", " << y;
      }
    }
  }
  SamplingConfig sampling;
  sampling.foreground_fraction = 0.0;
  sampling.boundary_fraction = 1.0;
  std::mt19937 rng(3);
  const auto [v, t] = sampler.UsableFrames().front();
  const std::vector<int>& band = sampler.BoundaryPixels(v, t);
  const std::set<int> in_band(band.begin(), band.end());
  const int width = data.videos[v].frames[t].mask.cols;
  for (const Ray& ray : sampler.SampleFrame(v, t, 500, 2, sampling, *model, kBounds, &rng)) {
    EXPECT_TRUE(in_band.count(static_cast<int>(ray.uv.y()) * width + static_cast<int>(ray.uv.x())) >
                0);
  }
}

// Active sampling draws near the pixels with the largest recorded errors.
TEST_F(RaySamplerTest, ActiveRaysRevisitLargeErrors) {
  SamplingConfig sampling;
  std::mt19937 rng(2);
  const std::vector<Ray> first = sampler.Sample(64, 8, sampling, *model, kBounds, &rng);
  std::vector<double> errors(first.size(), 0.0);
  errors[0] = 100.0;  // one ray with a huge error
  sampler.RecordErrors(first, errors);
  ASSERT_FALSE(sampler.error_cache().empty());
  sampling.active_fraction = 1.0;
  const std::vector<Ray> active = sampler.Sample(32, 8, sampling, *model, kBounds, &rng);
  int near = 0;
  for (const Ray& ray : active) {
    near += ray.video == first[0].video && ray.frame == first[0].frame &&
            (ray.uv - first[0].uv).norm() < 4.0;
  }
  // Error-proportional: every other cached pixel has error 0.
  EXPECT_EQ(near, 32) << "active rays away from the only pixel with an error";
}

// The error cache is a window of the most recent rays: a huge error ages out
// after kErrorWindow newer rays (before, the largest errors ever seen stayed
// and stage 3's active rays revisited pixels of stage 1's early model).
TEST_F(RaySamplerTest, OldErrorsAgeOutOfTheCache) {
  SamplingConfig sampling;
  std::mt19937 rng(3);
  const std::vector<Ray> first = sampler.Sample(64, 8, sampling, *model, kBounds, &rng);
  std::vector<double> errors(first.size(), 1.0);
  errors[0] = 1e6;
  sampler.RecordErrors(first, errors);
  auto has_huge = [&] {
    for (const RaySampler::CachedPixel& p : sampler.error_cache()) {
      if (p.error > 1.0) return true;
    }
    return false;
  };
  const size_t batch = 512;
  size_t newer = 0;
  while (newer + batch < RaySampler::kErrorWindow) {
    const std::vector<Ray> rays = sampler.Sample(batch, 2, sampling, *model, kBounds, &rng);
    sampler.RecordErrors(rays, std::vector<double>(rays.size(), 1.0));
    newer += rays.size();
    ASSERT_TRUE(has_huge()) << "aged out after " << newer << " newer rays";
    ASSERT_LE(sampler.error_cache().size(), RaySampler::kErrorWindow);
  }
  const std::vector<Ray> rays = sampler.Sample(batch, 2, sampling, *model, kBounds, &rng);
  sampler.RecordErrors(rays, std::vector<double>(rays.size(), 1.0));
  EXPECT_FALSE(has_huge());
  EXPECT_EQ(sampler.error_cache().size(), RaySampler::kErrorWindow);
}

// An all-zero feature vector is no feature (docs/dataset.md): features
// computed only where they are known (a lost track) leave the rest zero, and
// such rays must not pull the embedding toward the zero vector.
TEST(RaySamplerFeatures, ZeroFeaturesAreNone) {
  Dataset data = testing::TinyQuadrupedDataset();
  int zeroed = 0;
  for (Video& video : data.videos) {
    for (Frame& f : video.frames) {
      ASSERT_FALSE(f.features.empty());
      f.features = f.features.clone();
      // Assigning a zero Scalar clears all 16 channels (setTo takes at most 4).
      f.features(cv::Rect(0, 0, f.features.cols / 2, f.features.rows)) = cv::Scalar::all(0);
      zeroed += cv::countNonZero(f.mask.colRange(0, f.mask.cols / 2) == kMaskObject) > 0;
    }
  }
  ASSERT_GT(zeroed, 0);
  const std::unique_ptr<Model> model =
      MakeModelForDataset(data, testing::TinySolverConfig(StepRule::kAdam, 1).model);
  RaySampler sampler(data);
  SamplingConfig sampling;
  std::mt19937 rng(11);
  int left = 0, right = 0;
  for (const Ray& ray : sampler.Sample(400, 8, sampling, *model, kBounds, &rng)) {
    if (ray.mask < 0.5) continue;
    const int cols = data.videos[ray.video].frames[ray.frame].features.cols;
    const bool in_zeroed_half = static_cast<int>(ray.uv.x()) < cols / 2;
    EXPECT_EQ(ray.has_feature, !in_zeroed_half) << "pixel " << ray.uv.transpose();
    (in_zeroed_half ? left : right) += 1;
  }
  EXPECT_GT(left, 0);
  EXPECT_GT(right, 0);
}

}  // namespace
}  // namespace banmo
