// The render library (visualize/render.h, panels.h, sequence.h) on a tiny
// model trained in the test: rendered values are the observations plus the
// loss residuals and equal the full-Jet reference, error maps vanish where
// rendering and observation agree, and the pictures agree with the data's
// mask where the model is good (and not for an untrained model).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>

#include "banmo/extract/extract.h"
#include "banmo/losses/ray_batch.h"
#include "banmo/losses/ray_reference.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/util/error.h"
#include "banmo/visualize/panels.h"
#include "banmo/visualize/render.h"
#include "banmo/visualize/sequence.h"
#include "banmo/volume/ray_samples.h"
#include "trained_tiny_model.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::TinyQuadrupedDataset;
using testing::TrainedTinyModel;
using testing::UntrainedTinyModel;

FrameRenderOptions TinyRenderOptions(const Model& model) {
  FrameRenderOptions o;
  o.samples_per_ray = 16;  // as the training config
  o.canonical_bounds = CanonicalBoundsFromSurface(model);
  o.chunk_rays = 1000;  // several chunks per 48 x 48 frame, last one partial
  return o;
}

// Mean over every frame of the dataset of the rendered-mask IoU.
double MeanMaskIou(const Model& model) {
  const Dataset& data = TinyQuadrupedDataset();
  const FrameRenderOptions options = TinyRenderOptions(model);
  double sum = 0.0;
  int n = 0;
  for (int v = 0; v < static_cast<int>(data.videos.size()); ++v) {
    for (int t = 0; t < static_cast<int>(data.videos[v].frames.size()); ++t) {
      const ObservedFrame observed = ObserveFrame(data, v, t, 1);
      const RenderedFrame rendered = RenderFrame(model, observed, options);
      sum += SummarizeErrors(ComputeErrorMaps(rendered, observed), rendered, observed).mask_iou;
      ++n;
    }
  }
  return sum / n;
}

TEST(RenderFrame, RenderedValuesDoNotDependOnTheObservationsCarried) {
  // rendered = observed + residual: with other observations in the rays
  // (inverted colours, shifted flow) the residuals change and the rendered
  // values must not. 1e-12: only the rounding of (c - c_hat) + c_hat.
  const Model& model = TrainedTinyModel();
  const Dataset& data = TinyQuadrupedDataset();
  const FrameRenderOptions options = TinyRenderOptions(model);
  const ObservedFrame observed = ObserveFrame(data, 1, 2, 1);
  ASSERT_EQ(observed.partner_frame, 3);
  // (New matrices: assigning an expression to a shared cv::Mat header
  // would write into the original's pixels.)
  ObservedFrame other = observed;
  other.rgb = cv::Mat();
  other.flow = cv::Mat();
  cv::subtract(cv::Scalar::all(1.0), observed.rgb, other.rgb);
  cv::add(observed.flow, cv::Scalar(3.0, -2.0), other.flow);
  const RenderedFrame a = RenderFrame(model, observed, options);
  const RenderedFrame b = RenderFrame(model, other, options);
  EXPECT_LE(cv::norm(a.rgb, b.rgb, cv::NORM_INF), 1e-12);
  EXPECT_LE(cv::norm(a.opacity, b.opacity, cv::NORM_INF), 1e-12);
  EXPECT_LE(cv::norm(a.flow, b.flow, cv::NORM_INF), 1e-12);
  // And the observation really was used: the residuals differ by the shift.
  EXPECT_GT(cv::norm(a.rgb - observed.rgb, b.rgb - other.rgb, cv::NORM_INF), 0.5);
}

TEST(RenderFrame, EqualsTheFullJetReferenceResidualPlusObservation) {
  // An independent evaluation of single rays (the full-Jet reference cost
  // functions, ray_reference.h) built here the way the renderer documents:
  // pixel centre, midpoint samples between the frame's near/far planes,
  // mask 1, flow to the partner frame. Catches swapped pixel indices too.
  // 1e-9: the reference and the mixed-mode pipeline agree to ~1e-12 in
  // tests/losses; rendered values are O(1).
  const Model& model = TrainedTinyModel();
  const Dataset& data = TinyQuadrupedDataset();
  FrameRenderOptions options = TinyRenderOptions(model);
  options.skip_rays_outside_box = false;  // the corner pixels miss the box
  const int v = 0, t = 5;
  const ObservedFrame observed = ObserveFrame(data, v, t, 1);
  ASSERT_EQ(observed.partner_frame, 4);  // last frame: t - gap
  const RenderedFrame rendered = RenderFrame(model, observed, options);

  double near, far;
  NearFarPlanes(model.RootPose(v, t), options.canonical_bounds, options.near_far_margin, &near,
                &far);
  const Eigen::Vector4d& k = model.video(v).intrinsics;
  const std::vector<std::pair<int, int>> pixels = {{24, 20}, {10, 30}, {31, 17}, {0, 47}, {47, 3}};
  std::vector<Ray> rays;
  for (const auto& [x, y] : pixels) {
    Ray ray;
    ray.video = v;
    ray.frame = t;
    ray.uv = Eigen::Vector2d(x + 0.5, y + 0.5);
    const cv::Vec3d c = observed.rgb.at<cv::Vec3d>(y, x);
    ray.rgb = Eigen::Vector3d(c[0], c[1], c[2]);
    ray.mask = 1.0;
    ray.partner_frame = observed.partner_frame;
    ray.has_flow = true;
    const cv::Vec2d f = observed.flow.at<cv::Vec2d>(y, x);
    ray.flow = Eigen::Vector2d(f[0], f[1]);
    ray.samples = StratifiedSamples(options.samples_per_ray, near, far,
                                    RayDirectionLength(k, ray.uv), false, nullptr);
    rays.push_back(ray);
  }
  RayBatchOptions batch_options;
  batch_options.weights =
      RayLossWeights::Only({LossTerm::kRgb, LossTerm::kSilhouette, LossTerm::kFlow});
  RayBatch batch(model, batch_options);
  batch.SetRays(rays);
  int object_pixels = 0;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const auto [x, y] = pixels[i];
    double value[3];
    auto evaluate = [&](LossTerm term) {
      const std::unique_ptr<ceres::CostFunction> cost =
          MakeReferenceCostFunction(batch, static_cast<int>(i), term);
      const std::vector<const double*> blocks = batch.TermBlockValues(static_cast<int>(i), term);
      ASSERT_TRUE(cost->Evaluate(blocks.data(), value, nullptr));
    };
    evaluate(LossTerm::kRgb);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(rendered.rgb.at<cv::Vec3d>(y, x)[c], rays[i].rgb[c] + value[c], 1e-9)
          << x << "," << y;
    }
    evaluate(LossTerm::kSilhouette);
    EXPECT_NEAR(rendered.opacity.at<double>(y, x), 1.0 + value[0], 1e-9) << x << "," << y;
    evaluate(LossTerm::kFlow);
    for (int c = 0; c < 2; ++c) {
      EXPECT_NEAR(rendered.flow.at<cv::Vec2d>(y, x)[c], rays[i].flow[c] + value[c], 1e-9)
          << x << "," << y;
    }
    object_pixels += observed.mask.at<double>(y, x) > 0.5;
  }
  // The chosen pixels cover object and background.
  EXPECT_GT(object_pixels, 0);
  EXPECT_LT(object_pixels, static_cast<int>(pixels.size()));
}

// The three pictures of two renderings agree within tol (rounding only).
void ExpectSameImages(const RenderedFrame& a, const RenderedFrame& b, double tol,
                      const std::string& what) {
  EXPECT_LE(cv::norm(a.rgb, b.rgb, cv::NORM_INF), tol) << what;
  EXPECT_LE(cv::norm(a.opacity, b.opacity, cv::NORM_INF), tol) << what;
  EXPECT_LE(cv::norm(a.flow, b.flow, cv::NORM_INF), tol) << what;
}

TEST(RenderFrame, ChunkSizeDoesNotChangeTheResult) {
  // Chunks are a memory bound only: one chunk, chunks of 1000 (partial last
  // one) and of 7 rays give the same images, with and without importance
  // resampling (seeded per pixel, not per chunk). 1e-12: batched GEMMs of
  // different sizes may sum in another order (rounding only).
  const Model& model = TrainedTinyModel();
  const ObservedFrame observed = ObserveFrame(TinyQuadrupedDataset(), 0, 3, 2);
  ASSERT_EQ(observed.partner_frame, 5);
  cv::Mat opacity_without_importance;
  for (const bool importance : {false, true}) {
    FrameRenderOptions options = TinyRenderOptions(model);
    options.importance = importance;
    options.chunk_rays = 48 * 48;
    const RenderedFrame whole = RenderFrame(model, observed, options);
    if (!importance) opacity_without_importance = whole.opacity;
    // The importance pass does move the samples.
    if (importance) {
      EXPECT_GT(cv::norm(whole.opacity, opacity_without_importance, cv::NORM_INF), 1e-3);
    }
    for (const int chunk : {1000, 7}) {
      options.chunk_rays = chunk;
      const RenderedFrame parts = RenderFrame(model, observed, options);
      ExpectSameImages(whole, parts, 1e-12,
                       std::to_string(chunk) + (importance ? " importance" : ""));
    }
  }
}

TEST(RenderFrame, RaysOutsideTheBoxAreSkippedAndSawNothing) {
  // skip_rays_outside_box: the pixels whose rays miss the widened hit box
  // render empty; every other pixel is the same as with every ray
  // evaluated (seeds are per pixel; 1e-12 rounding as above), and the
  // evaluated rays of the skipped pixels saw (almost) nothing: opacity below
  // 0.01, the SDF's density more than the margin away from the surface.
  // The trained tiny model's box covers its whole 48 x 48 frames, so a copy
  // records the surface's box as its trained one: the hit box is then the
  // surface's, which some rays miss.
  const std::string dir =
      (fs::temp_directory_path() / ("banmo_render_hitbox_" + std::to_string(::getpid()))).string();
  SaveCheckpoint(dir, TrainedTinyModel(), CheckpointInfo());
  std::unique_ptr<Model> model = LoadCheckpoint(dir);
  fs::remove_all(dir);
  const FrameRenderOptions base = TinyRenderOptions(*model);
  ASSERT_TRUE(model->canonical_bounds());
  EXPECT_FALSE(base.canonical_bounds.contains(*model->canonical_bounds()));
  // The hit box holds the render's box and the trained one.
  EXPECT_TRUE(RenderHitBox(*model, base.canonical_bounds).contains(*model->canonical_bounds()));
  model->set_canonical_bounds(base.canonical_bounds);
  const Eigen::AlignedBox3d hit_box = RenderHitBox(*model, base.canonical_bounds);
  EXPECT_TRUE(hit_box.isApprox(base.canonical_bounds));
  const ObservedFrame observed = ObserveFrame(TinyQuadrupedDataset(), 0, 3, 2);
  for (const int passes : {0, 2}) {
    FrameRenderOptions options = base;
    options.importance = true;
    options.jitter_passes = passes;
    options.skip_rays_outside_box = false;
    const RenderedFrame all = RenderFrame(*model, observed, options);
    options.skip_rays_outside_box = true;
    const RenderedFrame skipped = RenderFrame(*model, observed, options);
    const Eigen::Vector4d& k = model->video(0).intrinsics;
    double near, far;
    NearFarPlanes(model->RootPose(0, 3), options.canonical_bounds, options.near_far_margin, &near,
                  &far);
    int outside = 0;
    for (int y = 0; y < observed.rgb.rows; ++y) {
      for (int x = 0; x < observed.rgb.cols; ++x) {
        double n = near, f = far;
        const bool hits = ClipDepthsToBox(model->RootPose(0, 3), hit_box, options.clip_margin, k,
                                          Eigen::Vector2d(x + 0.5, y + 0.5), &n, &f);
        if (hits) {
          EXPECT_LE(cv::norm(all.rgb.at<cv::Vec3d>(y, x) - skipped.rgb.at<cv::Vec3d>(y, x)), 1e-12);
          EXPECT_NEAR(all.opacity.at<double>(y, x), skipped.opacity.at<double>(y, x), 1e-12);
          continue;
        }
        ++outside;
        EXPECT_EQ(skipped.opacity.at<double>(y, x), 0.0);
        EXPECT_EQ(cv::norm(skipped.rgb.at<cv::Vec3d>(y, x)), 0.0);
        EXPECT_LT(all.opacity.at<double>(y, x), 0.01) << x << "," << y << " passes " << passes;
      }
    }
    // The case has pixels of both kinds.
    EXPECT_GT(outside, 0);
    EXPECT_LT(outside, observed.rgb.rows * observed.rgb.cols);
  }
}

TEST(RenderFrame, AddedImportanceSamplesAreSeededPerPixel) {
  // importance_samples K > 0 keeps the stratified samples and adds K: a
  // different rendering from the half-redrawn one, still independent of the
  // chunks (1e-12 as above), jittered or not.
  const Model& model = TrainedTinyModel();
  const ObservedFrame observed = ObserveFrame(TinyQuadrupedDataset(), 0, 3, 2);
  for (const int passes : {0, 2}) {
    FrameRenderOptions options = TinyRenderOptions(model);
    options.importance = true;
    options.jitter_passes = passes;
    options.chunk_rays = 48 * 48;
    const RenderedFrame half = RenderFrame(model, observed, options);
    options.importance_samples = 16;
    const RenderedFrame added = RenderFrame(model, observed, options);
    EXPECT_GT(cv::norm(added.opacity, half.opacity, cv::NORM_INF), 1e-3) << passes;
    options.chunk_rays = 7;
    const RenderedFrame parts = RenderFrame(model, observed, options);
    ExpectSameImages(added, parts, 1e-12, std::to_string(passes) + " passes");
  }
  FrameRenderOptions bad = TinyRenderOptions(model);
  bad.importance_samples = -1;
  EXPECT_THROW(bad.Check(), InputError);
}

TEST(RenderFrame, JitteredPassesAreSeededPerPixelAndMoveTheSamples) {
  // jitter_passes K > 0 averages K renderings with jittered depths: seeded
  // per pass and pixel, so chunks do not change it (1e-12 as above) and a
  // second call gives the same images; it differs from the midpoint
  // rendering (the samples moved) and, with K = 2, from K = 1.
  const Model& model = TrainedTinyModel();
  const ObservedFrame observed = ObserveFrame(TinyQuadrupedDataset(), 0, 3, 2);
  for (const bool importance : {false, true}) {
    FrameRenderOptions options = TinyRenderOptions(model);
    options.importance = importance;
    const RenderedFrame midpoints = RenderFrame(model, observed, options);
    options.jitter_passes = 1;
    const RenderedFrame one = RenderFrame(model, observed, options);
    options.jitter_passes = 2;
    options.chunk_rays = 48 * 48;
    const RenderedFrame two = RenderFrame(model, observed, options);
    EXPECT_GT(cv::norm(one.opacity, midpoints.opacity, cv::NORM_INF), 1e-3) << importance;
    EXPECT_GT(cv::norm(two.opacity, one.opacity, cv::NORM_INF), 1e-3) << importance;
    options.chunk_rays = 7;
    const RenderedFrame again = RenderFrame(model, observed, options);
    ExpectSameImages(two, again, 1e-12, importance ? "importance" : "");
    // A mean of opacities in [0, 1] stays there (up to rounding).
    double lo, hi;
    cv::minMaxLoc(two.opacity, &lo, &hi);
    EXPECT_GE(lo, -1e-12);
    EXPECT_LE(hi, 1.0 + 1e-12);
  }
}

TEST(ErrorMaps, ZeroWhereRenderedEqualsObservedAndTheDifferenceElsewhere) {
  const Model& model = TrainedTinyModel();
  const ObservedFrame real = ObserveFrame(TinyQuadrupedDataset(), 0, 1, 1);
  const RenderedFrame rendered = RenderFrame(model, real, TinyRenderOptions(model));
  // Observations equal to the rendering: every defined error is exactly 0.
  ObservedFrame same = real;
  same.rgb = rendered.rgb.clone();
  same.flow = rendered.flow.clone();
  same.flow_valid = cv::Mat(real.rgb.size(), CV_8UC1, cv::Scalar(255));
  same.mask = rendered.opacity.clone();  // in [0, 1]: defined everywhere
  // One pixel differs.
  const int x = 20, y = 25;
  same.rgb.at<cv::Vec3d>(y, x) += cv::Vec3d(0.3, -0.3, 0.0);
  same.mask.at<double>(y, x) = 1.0;
  same.flow.at<cv::Vec2d>(y, x) += cv::Vec2d(3.0, 4.0);
  const ErrorMaps e = ComputeErrorMaps(rendered, same);
  int defined_rgb = 0;
  for (int j = 0; j < e.rgb.rows; ++j) {
    for (int i = 0; i < e.rgb.cols; ++i) {
      if (i == x && j == y) continue;
      const double m = same.mask.at<double>(j, i);
      EXPECT_EQ(e.mask.at<double>(j, i), 0.0);
      if (m >= 0.5) {
        EXPECT_EQ(e.rgb.at<double>(j, i), 0.0);
        EXPECT_EQ(e.flow.at<double>(j, i), 0.0);
        ++defined_rgb;
      } else {  // rgb and flow errors only on object pixels, as the losses
        EXPECT_TRUE(std::isnan(e.rgb.at<double>(j, i)));
        EXPECT_TRUE(std::isnan(e.flow.at<double>(j, i)));
      }
    }
  }
  EXPECT_GT(defined_rgb, 50);
  EXPECT_NEAR(e.rgb.at<double>(y, x), 0.2, 1e-12);  // (0.3 + 0.3 + 0) / 3
  EXPECT_NEAR(e.mask.at<double>(y, x), 1.0 - rendered.opacity.at<double>(y, x), 1e-12);
  EXPECT_NEAR(e.flow.at<double>(y, x), 5.0, 1e-12);
  // Unknown mask pixels have no mask error; missing flow no flow error.
  ObservedFrame unknown = same;
  unknown.mask.at<double>(y, x) = -1.0;
  unknown.flow_valid.setTo(0);
  const ErrorMaps u = ComputeErrorMaps(rendered, unknown);
  EXPECT_TRUE(std::isnan(u.mask.at<double>(y, x)));
  EXPECT_TRUE(std::isnan(u.rgb.at<double>(y, x)));
  EXPECT_EQ(cv::countNonZero(u.flow == u.flow), 0);  // all NaN
}

TEST(RenderFrame, TrainedMaskAgreesWithTheDataAndUntrainedDoesNot) {
  const double trained = MeanMaskIou(TrainedTinyModel());
  const std::unique_ptr<Model> untrained = UntrainedTinyModel();
  const double initial = MeanMaskIou(*untrained);
  std::printf("mean mask IoU over the 12 frames: trained %.3f, untrained %.3f\n", trained, initial);
  // Measured 0.581 trained, 0.447 untrained (the initial sphere); the bound
  // sits between them.
  EXPECT_GT(trained, 0.52);
  EXPECT_LT(initial, 0.52);
}

TEST(Panels, SizesAndMaskPanelColours) {
  const Model& model = TrainedTinyModel();
  const ObservedFrame observed = ObserveFrame(TinyQuadrupedDataset(), 1, 0, 1);
  const RenderedFrame rendered = RenderFrame(model, observed, TinyRenderOptions(model));
  RenderSequenceOptions options;
  options.scale = 3;
  options.labels = false;  // so panel pixels can be compared exactly
  PinholeCamera camera = model.video(1).camera;
  const cv::Mat panels =
      FramePanels(observed, rendered, TriangleMesh(), TriangleMesh(), camera, options);
  const int w = observed.rgb.cols, h = observed.rgb.rows;
  ASSERT_EQ(panels.cols, 5 * w * 3);
  ASSERT_EQ(panels.rows, h * 3);
  ASSERT_EQ(panels.type(), CV_8UC3);
  const cv::Mat errors = ErrorPanels(ComputeErrorMaps(rendered, observed), options);
  EXPECT_EQ(errors.cols, 3 * w * 3);
  EXPECT_EQ(errors.rows, h * 3);
  // Panel 1 is the input, panel 3 the mask agreement, pixel by pixel.
  const cv::Mat agreement = MaskAgreementImage(rendered.opacity, observed.mask);
  int both = 0, neither = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const cv::Vec3b in = panels.at<cv::Vec3b>(3 * y + 1, 3 * x + 1);
      EXPECT_EQ(in, TinyQuadrupedDataset().videos[1].frames[0].rgb.at<cv::Vec3b>(y, x));
      const cv::Vec3b m = panels.at<cv::Vec3b>(3 * y + 1, 2 * 3 * w + 3 * x + 1);
      EXPECT_EQ(m, agreement.at<cv::Vec3b>(y, x));
      const bool rendered_object = rendered.opacity.at<double>(y, x) >= 0.5;
      const bool input_object = observed.mask.at<double>(y, x) >= 0.5;
      const cv::Vec3b expected =
          input_object ? (rendered_object ? kMaskBothColor : kMaskInputOnlyColor)
                       : (rendered_object ? kMaskRenderedOnlyColor : kMaskNeitherColor);
      EXPECT_EQ(m, expected);
      both += m == kMaskBothColor;
      neither += m == kMaskNeitherColor;
    }
  }
  const double agree = static_cast<double>(both + neither) / (w * h);
  std::printf("video 1 frame 0: rendered and input mask agree on %.1f %% of the pixels\n",
              100.0 * agree);
  EXPECT_GT(agree, 0.9);  // measured 94.4 %
  EXPECT_GT(both, 0);
  // Empty meshes give black mesh panels.
  EXPECT_EQ(cv::countNonZero(panels.colRange(3 * 3 * w, 5 * 3 * w).reshape(1)), 0);
}

TEST(Panels, ShadedMeshLandsWhereTheVolumeRenderingSeesTheObject) {
  // The articulated mesh (zero level set, posed by ArticulateMesh) rasterised
  // with the frame's camera against the volume-rendered opacity of the same
  // model: two routes from one model, so they must cover the same pixels
  // whatever the quality of the fit. A flipped axis, a wrong root pose or
  // camera would put the mesh elsewhere (IoU near 0).
  const Model& model = TrainedTinyModel();
  const Dataset& data = TinyQuadrupedDataset();
  const FrameRenderOptions options = TinyRenderOptions(model);
  ExtractOptions extract;
  extract.grid.resolution = 64;
  extract.grid.bounds_min = options.canonical_bounds.min();
  extract.grid.bounds_max = options.canonical_bounds.max();
  const TriangleMesh canonical = ExtractCanonicalMesh(model, extract);
  ASSERT_GT(canonical.NumFaces(), 0);
  for (const auto& [v, t] : std::vector<std::pair<int, int>>{{0, 2}, {1, 3}}) {
    PinholeCamera camera = model.video(v).camera;
    camera.intrinsics = model.video(v).intrinsics;
    const cv::Mat shaded = ShadeMesh(ArticulateMesh(model, canonical, v, t), camera);
    const RenderedFrame rendered = RenderFrame(model, ObserveFrame(data, v, t, 1), options);
    int inter = 0, uni = 0;
    for (int y = 0; y < shaded.rows; ++y) {
      for (int x = 0; x < shaded.cols; ++x) {
        const bool a = shaded.at<cv::Vec3b>(y, x) != cv::Vec3b(0, 0, 0);
        const bool b = rendered.opacity.at<double>(y, x) >= 0.5;
        inter += a && b;
        uni += a || b;
      }
    }
    const double iou = static_cast<double>(inter) / uni;
    std::printf("video %d frame %d: shaded mesh vs rendered mask IoU %.3f\n", v, t, iou);
    EXPECT_GT(iou, 0.8);
  }
}

TEST(RenderSequence, WritesOnePngPerFrameTheErrorMapsAndTheTable) {
  const Model& model = TrainedTinyModel();
  const Dataset& data = TinyQuadrupedDataset();
  const fs::path out = fs::temp_directory_path() / ("banmo_volume_seq_" + std::to_string(getpid()));
  fs::remove_all(out);
  RenderSequenceOptions options;
  options.frame = TinyRenderOptions(model);
  options.mesh_resolution = 48;
  options.scale = 2;
  options.turntable_views = 3;
  options.write_video = true;
  const std::vector<std::pair<int, int>> frames = {{0, 0}, {1, 5}};
  int calls = 0;
  const SequenceSummary s = RenderSequence(model, data, frames, options, out.string(),
                                           [&](const FrameReport&, int, int) { ++calls; });
  EXPECT_EQ(calls, 2);
  ASSERT_EQ(s.frames.size(), 2u);
  EXPECT_GT(s.mesh_vertices, 0);
  EXPECT_EQ(s.turntable_written, 3);
  for (const auto& [v, t] : frames) {
    const cv::Mat png = cv::imread((out / "frames" / (FrameStem(v, t) + ".png")).string());
    ASSERT_FALSE(png.empty());
    EXPECT_EQ(png.cols, 5 * 48 * 2);
    EXPECT_EQ(png.rows, 48 * 2);
    // Both mesh panels show the object.
    EXPECT_GT(cv::countNonZero(png.colRange(3 * 96, 4 * 96).reshape(1)), 100);
    EXPECT_GT(cv::countNonZero(png.colRange(4 * 96, 5 * 96).reshape(1)), 100);
    const cv::Mat err = cv::imread((out / "errors" / (FrameStem(v, t) + ".png")).string());
    EXPECT_EQ(err.cols, 3 * 48 * 2);
    EXPECT_EQ(err.rows, 48 * 2);
  }
  EXPECT_TRUE(fs::exists(out / "turntable" / "view002.png"));
  // The MP4 (Debian's OpenCV + FFmpeg accept avc1) reads back frame by frame.
  ASSERT_EQ(s.video_path, (out / "sequence.mp4").string()) << s.video_note;
  cv::VideoCapture capture(s.video_path);
  ASSERT_TRUE(capture.isOpened());
  int read = 0;
  cv::Mat image;
  while (capture.read(image)) {
    EXPECT_EQ(image.cols, 5 * 48 * 2);
    EXPECT_EQ(image.rows, 48 * 2);
    ++read;
  }
  EXPECT_EQ(read, 2);
  EXPECT_EQ(s.turntable_video_path, (out / "turntable.mp4").string());
  EXPECT_GT(fs::file_size(out / "turntable.mp4"), 0u);
  std::ifstream csv(out / "errors.csv");
  std::string line;
  int lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 3);  // header + 2 frames
  fs::remove_all(out);
}

TEST(CheckDatasetMatchesModel, NamesWhatDiffers) {
  const std::unique_ptr<Model> untrained = UntrainedTinyModel();
  const Model& model = *untrained;
  Dataset data = TinyQuadrupedDataset();
  EXPECT_NO_THROW(CheckDatasetMatchesModel(data, model, "DATA"));
  Dataset fewer = data;
  fewer.videos.pop_back();
  EXPECT_THROW(
      {
        try {
          CheckDatasetMatchesModel(fewer, model, "DATA");
        } catch (const InputError& e) {
          EXPECT_NE(std::string(e.what()).find("DATA: the dataset has 1 videos, the model 2"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      InputError);
  Dataset short_video = data;
  short_video.videos[1].frames.pop_back();
  EXPECT_THROW(CheckDatasetMatchesModel(short_video, model, "DATA"), InputError);
  Dataset resized = data;
  resized.videos[0].camera.width = 64;
  EXPECT_THROW(CheckDatasetMatchesModel(resized, model, "DATA"), InputError);
  Dataset other_focal = data;
  other_focal.videos[0].camera.intrinsics[0] *= 1.01;
  EXPECT_THROW(CheckDatasetMatchesModel(other_focal, model, "DATA"), InputError);
}

TEST(FrameRenderOptions, CheckNamesTheField) {
  FrameRenderOptions o;
  o.samples_per_ray = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = FrameRenderOptions();
  o.canonical_bounds = Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 1));
  EXPECT_THROW(o.Check(), InputError);
  o = FrameRenderOptions();
  o.flow_gap = 0;
  EXPECT_THROW(o.Check(), InputError);
  o = FrameRenderOptions();
  o.jitter_passes = -1;
  EXPECT_THROW(o.Check(), InputError);
  o = FrameRenderOptions();
  o.clip_margin = -0.1;
  try {
    o.Check();
    ADD_FAILURE() << "a negative clip_margin passed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("clip_margin"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace banmo
