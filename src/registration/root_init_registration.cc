#include "banmo/registration/root_init_registration.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "banmo/geometry/nearest_rotation.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/geometry/se3.h"
#include "banmo/registration/root_init_smoothing.h"
#include "banmo/util/median.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

// Feature-space constants, for unit-norm features (the synthetic scenes'
// per-pixel noise is about 0.2 in norm, neighbouring references are about
// 0.37 apart at 300 references).
constexpr double kMatchSigma = 0.1;        // soft-argmin temperature (feature distance)
constexpr double kMaxMatchDistance = 0.3;  // a reference's best distance must be below this
constexpr double kMaxSpreadPx = 3.0;       // ... and its soft match this compact
constexpr int kReferenceSample = 30000;    // features the references are picked from
constexpr int kMinFrameObservations = 6;   // an affine camera has 8 unknowns, 2 per observation
constexpr int kAlsIterations = 200;
constexpr int kAlsStarts = 3;
constexpr double kCauchyScalePx = 2.0;
constexpr uint64_t kSeed = 0x5eed2e915u;
// A video takes the registration when its initial track's noise is this
// many times the registered track's (exact synthetic tracks: 0.3 deg
// against 0.5-0.7 registered; Gaussian 20 deg: about 12).
constexpr double kNoiseRatio = 2.0;
// Registration cost over its depth reversal's above which the registration
// is called ambiguous (`quad`, the Fox, the hand: 0.54-0.65; the bird,
// whose wings move more than its body: 0.90).
constexpr double kAmbiguousCostRatio = 0.8;

using Matrix23 = Eigen::Matrix<double, 2, 3>;

struct Observation {
  int frame;           // index into the registered frame list
  int point;           // reference
  Eigen::Vector2d uv;  // normalised image coordinates ((x - cx) / fx, (y - cy) / fy)
};

struct FrameRef {
  int video;
  int frame;
};

// The features of one frame's object pixels that have one (IsPixelFeature:
// an all-zero vector is none) (kFeatureDim x N) and their pixel centres
// (2 x N).
void ObjectFeatures(const Frame& f, Eigen::MatrixXf* features, Eigen::Matrix2Xd* pixels) {
  const int n = cv::countNonZero(f.mask == kMaskObject);
  features->resize(kFeatureDim, n);
  pixels->resize(2, n);
  int k = 0;
  for (int y = 0; y < f.mask.rows; ++y) {
    const unsigned char* m = f.mask.ptr<unsigned char>(y);
    const cv::float16_t* e = f.features.ptr<cv::float16_t>(y);
    for (int x = 0; x < f.mask.cols; ++x) {
      const cv::float16_t* feature = e + x * kFeatureDim;
      if (m[x] != kMaskObject || !IsPixelFeature(feature)) continue;
      for (int c = 0; c < kFeatureDim; ++c) (*features)(c, k) = static_cast<float>(feature[c]);
      (*pixels)(0, k) = x + 0.5;
      (*pixels)(1, k) = y + 0.5;
      ++k;
    }
  }
  features->conservativeResize(Eigen::NoChange, k);
  pixels->conservativeResize(Eigen::NoChange, k);
}

// Farthest-point sampling of `count` columns of `sample` (deterministic:
// starts from column 0).
Eigen::MatrixXf FarthestPoints(const Eigen::MatrixXf& sample, int count) {
  const int n = static_cast<int>(sample.cols());
  count = std::min(count, n);
  Eigen::MatrixXf out(sample.rows(), count);
  Eigen::VectorXf dist = Eigen::VectorXf::Constant(n, std::numeric_limits<float>::infinity());
  int next = 0;
  for (int i = 0; i < count; ++i) {
    out.col(i) = sample.col(next);
    dist = dist.cwiseMin((sample.colwise() - sample.col(next)).colwise().squaredNorm().transpose());
    dist.maxCoeff(&next);
  }
  return out;
}

// Soft matches of the references in one frame; appends observations.
void MatchFrame(const Eigen::MatrixXf& refs, const Eigen::MatrixXf& features,
                const Eigen::Matrix2Xd& pixels, const Eigen::Vector4d& intrinsics, int frame,
                std::vector<Observation>* out) {
  if (features.cols() == 0) return;
  const Eigen::MatrixXf d2 =
      ((-2.0f * refs.transpose() * features).colwise() + refs.colwise().squaredNorm().transpose())
          .rowwise() +
      features.colwise().squaredNorm();
  const double inv = 1.0 / (2 * kMatchSigma * kMatchSigma);
  for (int p = 0; p < refs.cols(); ++p) {
    const float dmin = d2.row(p).minCoeff();
    if (!(std::sqrt(std::max(dmin, 0.0f)) < kMaxMatchDistance)) continue;
    double wsum = 0;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    Eigen::VectorXd w(features.cols());
    for (int k = 0; k < features.cols(); ++k) {
      w[k] = std::exp(-(d2(p, k) - dmin) * inv);
      wsum += w[k];
      mean += w[k] * pixels.col(k);
    }
    mean /= wsum;
    double spread2 = 0;
    for (int k = 0; k < features.cols(); ++k) {
      spread2 += w[k] * (pixels.col(k) - mean).squaredNorm();
    }
    if (!(std::sqrt(spread2 / wsum) < kMaxSpreadPx)) continue;
    const Eigen::Vector2d uv((mean[0] - intrinsics[2]) / intrinsics[0],
                             (mean[1] - intrinsics[3]) / intrinsics[1]);
    out->push_back({frame, p, uv});
  }
}

// s x (the nearest matrix with orthonormal rows), s the singular values' mean.
Matrix23 ScaledOrthonormal(const Matrix23& a) {
  // (a a^T)^(-1/2) a has orthonormal rows; a's singular values are the
  // square roots of a a^T's eigenvalues.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(a * a.transpose());
  const Eigen::Vector2d lambda = eig.eigenvalues().cwiseMax(1e-300);
  const double s = 0.5 * (std::sqrt(lambda[0]) + std::sqrt(lambda[1]));
  const Eigen::Matrix2d inv_sqrt = eig.eigenvectors() *
                                   lambda.cwiseSqrt().cwiseInverse().asDiagonal() *
                                   eig.eigenvectors().transpose();
  return s * inv_sqrt * a;
}

struct Factorisation {
  std::vector<Matrix23> a;         // s_t R_t[0:2]
  std::vector<Eigen::Vector2d> b;  // offsets
  std::vector<bool> frame_ok;      // enough observations
  Eigen::Matrix3Xd points;
  std::vector<bool> point_ok;                            // observed at least twice
  double rms = std::numeric_limits<double>::infinity();  // normalised units
};

// Alternating least squares of the weak-perspective factorisation from
// random points drawn with `rng`.
Factorisation Factorise(const std::vector<std::vector<int>>& by_frame,
                        const std::vector<std::vector<int>>& by_point,
                        const std::vector<Observation>& obs, std::mt19937_64* rng) {
  const int nf = static_cast<int>(by_frame.size()), np = static_cast<int>(by_point.size());
  Factorisation f;
  f.a.assign(nf, Matrix23::Zero());
  f.b.assign(nf, Eigen::Vector2d::Zero());
  f.frame_ok.assign(nf, false);
  f.point_ok.assign(np, false);
  f.points.resize(3, np);
  std::normal_distribution<double> normal(0.0, 0.3);
  for (int p = 0; p < np; ++p) {
    for (int k = 0; k < 3; ++k) f.points(k, p) = normal(*rng);
    f.point_ok[p] = by_point[p].size() >= 2;
  }
  for (int it = 0; it < kAlsIterations; ++it) {
    for (int t = 0; t < nf; ++t) {
      const std::vector<int>& ids = by_frame[t];
      if (static_cast<int>(ids.size()) < kMinFrameObservations) continue;
      Eigen::Matrix4d hth = Eigen::Matrix4d::Zero();
      Eigen::Matrix<double, 4, 2> hty = Eigen::Matrix<double, 4, 2>::Zero();
      for (int i : ids) {
        Eigen::Vector4d h;
        h << f.points.col(obs[i].point), 1.0;
        hth += h * h.transpose();
        hty += h * obs[i].uv.transpose();
      }
      const Eigen::Matrix<double, 4, 2> sol = hth.ldlt().solve(hty);
      f.a[t] = ScaledOrthonormal(sol.topRows<3>().transpose());
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (int i : ids) mean += obs[i].uv - f.a[t] * f.points.col(obs[i].point);
      f.b[t] = mean / static_cast<double>(ids.size());
      f.frame_ok[t] = true;
    }
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    int used = 0;
    for (int p = 0; p < np; ++p) {
      if (!f.point_ok[p]) continue;
      Eigen::Matrix3d mtm = Eigen::Matrix3d::Zero();
      Eigen::Vector3d mtr = Eigen::Vector3d::Zero();
      for (int i : by_point[p]) {
        const int t = obs[i].frame;
        if (!f.frame_ok[t]) continue;
        mtm += f.a[t].transpose() * f.a[t];
        mtr += f.a[t].transpose() * (obs[i].uv - f.b[t]);
      }
      // Seen from one direction only, a point's depth is undetermined.
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(mtm);
      if (eig.eigenvalues()[0] > 1e-6 * std::max(eig.eigenvalues()[2], 1e-300)) {
        f.points.col(p) = mtm.ldlt().solve(mtr);
      }
      centre += f.points.col(p);
      ++used;
    }
    if (used > 0) f.points.colwise() -= centre / used;
  }
  double sum = 0;
  int n = 0;
  for (const Observation& o : obs) {
    if (!f.frame_ok[o.frame] || !f.point_ok[o.point]) continue;
    sum += (f.a[o.frame] * f.points.col(o.point) + f.b[o.frame] - o.uv).squaredNorm();
    ++n;
  }
  f.rms = n > 0 ? std::sqrt(sum / n) : std::numeric_limits<double>::infinity();
  return f;
}

// Perspective reprojection error in pixels (focal lengths fx, fy).
struct ReprojectionError {
  ReprojectionError(const Eigen::Vector2d& uv, double fx, double fy) : uv_(uv), fx_(fx), fy_(fy) {}
  template <typename T>
  bool operator()(const T* camera_from_root, const T* point, T* residual) const {
    T x[3];
    PoseTransformPoint(camera_from_root, point, x);
    T z = x[2];
    if (z < T(1e-3)) z = T(1e-3);
    residual[0] = T(fx_) * (x[0] / z - T(uv_[0]));
    residual[1] = T(fy_) * (x[1] / z - T(uv_[1]));
    return true;
  }
  Eigen::Vector2d uv_;
  double fx_, fy_;
};

struct Adjusted {
  std::vector<Pose> poses;  // camera_from_registration, per registered frame
  double cost = 0.0;
  double median_px = 0.0;
  int iterations = 0;
};

// Bundle adjustment from the factorisation (mirrored: its depth reversal).
Adjusted Adjust(const Factorisation& f, bool mirrored, const std::vector<Observation>& obs,
                const std::vector<Eigen::Vector2d>& focal) {
  const int nf = static_cast<int>(f.a.size());
  const Eigen::Matrix3d d = Eigen::Vector3d(1, 1, mirrored ? -1 : 1).asDiagonal();
  Adjusted out;
  out.poses.assign(nf, PoseIdentity());
  Eigen::Matrix3Xd points = d * f.points;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::unique_ptr<ceres::Manifold> manifold = MakePoseManifold();
  ceres::CauchyLoss loss(kCauchyScalePx);
  std::vector<ceres::ResidualBlockId> residuals;
  int first = -1;
  for (int t = 0; t < nf; ++t) {
    if (!f.frame_ok[t]) continue;
    const double s = 0.5 * (f.a[t].row(0).norm() + f.a[t].row(1).norm());
    Eigen::Matrix3d r;
    r.row(0) = f.a[t].row(0).normalized();
    r.row(1) = f.a[t].row(1).normalized();
    r.row(2) = r.row(0).cross(r.row(1));
    r = d * r * d;
    const Eigen::Quaterniond q(r);
    Pose& p = out.poses[t];
    p << q.w(), q.x(), q.y(), q.z(), f.b[t][0] / s, f.b[t][1] / s, 1.0 / s;
  }
  for (const Observation& o : obs) {
    if (!f.frame_ok[o.frame] || !f.point_ok[o.point]) continue;
    auto* cost = new ceres::AutoDiffCostFunction<ReprojectionError, 2, kPoseSize, 3>(
        new ReprojectionError(o.uv, focal[o.frame][0], focal[o.frame][1]));
    residuals.push_back(problem.AddResidualBlock(cost, &loss, out.poses[o.frame].data(),
                                                 points.col(o.point).data()));
  }
  // A frame whose observations all see points observed once has no
  // residual (and keeps its factorisation pose).
  for (int t = 0; t < nf; ++t) {
    if (!problem.HasParameterBlock(out.poses[t].data())) continue;
    problem.SetManifold(out.poses[t].data(), manifold.get());
    // The first frame fixes the gauge (rotation, origin and, with its
    // depth, the scale).
    if (first < 0) {
      first = t;
      problem.SetParameterBlockConstant(out.poses[t].data());
    }
  }
  if (first < 0) return out;  // nothing to adjust
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_SCHUR;
  options.max_num_iterations = 100;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  out.cost = summary.final_cost;
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  ceres::Problem::EvaluateOptions eval;
  eval.residual_blocks = residuals;
  eval.apply_loss_function = false;
  std::vector<double> r;
  problem.Evaluate(eval, nullptr, &r, nullptr, nullptr);
  std::vector<double> norms(r.size() / 2);
  for (size_t i = 0; i < norms.size(); ++i) norms[i] = std::hypot(r[2 * i], r[2 * i + 1]);
  out.median_px = Median(std::move(norms));
  for (Pose& p : out.poses) p.segment<4>(kPoseQw).normalize();
  return out;
}

Eigen::Matrix3d PoseRotation(const Pose& p) { return IsometryFromPose(p.data()).linear(); }

// Chordal L1 mean of rotations (Weiszfeld).
Eigen::Matrix3d ChordalMedian(const std::vector<Eigen::Matrix3d>& m) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (const Eigen::Matrix3d& x : m) sum += x;
  Eigen::Matrix3d g = NearestRotation(sum);
  for (int it = 0; it < 30; ++it) {
    sum.setZero();
    for (const Eigen::Matrix3d& x : m) sum += x / std::max((x - g).norm(), 1e-9);
    g = NearestRotation(sum);
  }
  return g;
}

// The usable (not skipped) frames; false with result->reason when a frame
// has no features or fewer than 2 are usable.
bool UsableFrames(const Dataset& dataset, std::vector<FrameRef>* frames, RootRegistration* result) {
  for (int v = 0; v < static_cast<int>(dataset.videos.size()); ++v) {
    const Video& video = dataset.videos[v];
    for (int t = 0; t < static_cast<int>(video.frames.size()); ++t) {
      const Frame& f = video.frames[t];
      if (f.skip) continue;
      if (f.features.empty()) {
        result->reason = "video " + video.name + " frame " + std::to_string(t) + " has no features";
        return false;
      }
      frames->push_back({v, t});
    }
  }
  if (frames->size() < 2) {
    result->reason = "fewer than 2 usable frames";
    return false;
  }
  return true;
}

// Every usable frame's observations of the reference features.
struct Observations {
  std::vector<Observation> obs;
  std::vector<Eigen::Vector2d> focal;                // each frame's focal lengths
  std::vector<std::vector<int>> by_frame, by_point;  // indices into obs
  int references = 0;
};

// References: the farthest points of a random subset (drawn with *rng) of
// all frames' object features; each frame's features matched to them.
Observations ObserveReferences(const RootRegistrationOptions& options, const Dataset& dataset,
                               const std::vector<FrameRef>& frames, std::mt19937_64* rng) {
  const int nf = static_cast<int>(frames.size());
  std::vector<Eigen::MatrixXf> features(nf);
  std::vector<Eigen::Matrix2Xd> pixels(nf);
  ParallelFor(nf, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      ObjectFeatures(dataset.videos[frames[i].video].frames[frames[i].frame], &features[i],
                     &pixels[i]);
    }
  });
  std::vector<std::pair<int, int>> all;
  for (int i = 0; i < nf; ++i) {
    for (int k = 0; k < features[i].cols(); ++k) all.push_back({i, k});
  }
  if (static_cast<int>(all.size()) > kReferenceSample) {
    for (int k = 0; k < kReferenceSample; ++k) {
      std::uniform_int_distribution<size_t> pick(k, all.size() - 1);
      std::swap(all[k], all[pick(*rng)]);
    }
    all.resize(kReferenceSample);
  }
  Eigen::MatrixXf sample(features[0].rows(), static_cast<int>(all.size()));
  for (size_t k = 0; k < all.size(); ++k) sample.col(k) = features[all[k].first].col(all[k].second);
  const Eigen::MatrixXf refs = FarthestPoints(sample, options.references);
  Observations out;
  const int np = static_cast<int>(refs.cols());
  out.references = np;

  std::vector<std::vector<Observation>> per_frame(nf);
  out.focal.resize(nf);
  ParallelFor(nf, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector4d& k = dataset.videos[frames[i].video].camera.intrinsics;
      out.focal[i] = k.head<2>();
      MatchFrame(refs, features[i], pixels[i], k, i, &per_frame[i]);
    }
  });
  for (const auto& o : per_frame) out.obs.insert(out.obs.end(), o.begin(), o.end());
  out.by_frame.resize(nf);
  out.by_point.resize(np);
  for (int i = 0; i < static_cast<int>(out.obs.size()); ++i) {
    out.by_frame[out.obs[i].frame].push_back(i);
    out.by_point[out.obs[i].point].push_back(i);
  }
  return out;
}

// Each video's registered track in frame order (camera_from_registration;
// frames without a registration of their own take the nearest one's) beside
// its initial track.
struct VideoTracks {
  std::vector<std::vector<int>> source;  // the registered frame (index into frames) of each
  std::vector<std::vector<Pose>> registered, initial;
};

VideoTracks MakeVideoTracks(const Dataset& dataset, const std::vector<FrameRef>& frames,
                            const std::vector<std::vector<int>>& registered,
                            const std::vector<Pose>& poses) {
  const int nv = static_cast<int>(dataset.videos.size());
  VideoTracks out;
  out.source.resize(nv);
  out.registered.resize(nv);
  out.initial.resize(nv);
  for (int v = 0; v < nv; ++v) {
    const Video& video = dataset.videos[v];
    for (int t = 0; t < static_cast<int>(video.frames.size()); ++t) {
      int nearest = registered[v].front();
      for (int i : registered[v]) {
        if (std::abs(frames[i].frame - t) < std::abs(frames[nearest].frame - t)) nearest = i;
      }
      out.source[v].push_back(nearest);
      out.registered[v].push_back(poses[nearest]);
      out.initial[v].push_back(video.frames[t].root_pose_init);
    }
  }
  return out;
}

// Which videos take the registration (result->videos): all when the
// initial poses carry no rotation or `always`; otherwise those whose initial
// track is noisier than the registered one by kNoiseRatio, unless the
// registration is ambiguous (its depth reversal fits almost as well).
// True when some video keeps its initial poses.
bool ChooseVideos(const RootRegistrationOptions& options, const Dataset& dataset,
                  const VideoTracks& tracks, RootRegistration* result) {
  const bool carries = RootPosesCarryRotation(dataset);
  result->ambiguous = result->cost > kAmbiguousCostRatio * result->mirror_cost;
  const int nv = static_cast<int>(dataset.videos.size());
  result->videos.resize(nv);
  bool any_kept = false;
  for (int v = 0; v < nv; ++v) {
    VideoRegistration& c = result->videos[v];
    c.initial_noise_deg = RootTrackNoiseDeg(tracks.initial[v]);
    c.registered_noise_deg = RootTrackNoiseDeg(tracks.registered[v]);
    c.replaced = options.always || !carries ||
                 (!result->ambiguous && c.initial_noise_deg > kNoiseRatio * c.registered_noise_deg);
    any_kept = any_kept || !c.replaced;
  }
  return any_kept;
}

// The gauge of the registered tracks: the rotation onto the initial poses
// (those of the videos kept if any: they are the trusted ones) and the scale
// to their median depth. False when no frame of those videos has a
// registration of its own.
bool RegistrationGauge(const std::vector<FrameRef>& frames, const VideoTracks& tracks,
                       const RootRegistration& result, bool any_kept, Eigen::Matrix3d* gauge,
                       double* scale) {
  std::vector<Eigen::Matrix3d> offsets;
  std::vector<double> depth_init, depth_reg;
  for (size_t v = 0; v < tracks.registered.size(); ++v) {
    if (any_kept && result.videos[v].replaced) continue;
    for (size_t t = 0; t < tracks.registered[v].size(); ++t) {
      if (frames[tracks.source[v][t]].frame != static_cast<int>(t)) continue;  // not its own
      offsets.push_back(PoseRotation(tracks.registered[v][t]).transpose() *
                        PoseRotation(tracks.initial[v][t]));
      depth_init.push_back(tracks.initial[v][t][kPoseT + 2]);
      depth_reg.push_back(tracks.registered[v][t][kPoseT + 2]);
    }
  }
  if (offsets.empty()) return false;
  *gauge = ChordalMedian(offsets);
  const double di = Median(std::move(depth_init)), dr = Median(std::move(depth_reg));
  *scale = di > 0 && dr > 0 ? di / dr : 1.0;
  return true;
}

}  // namespace

bool RootPosesCarryRotation(const Dataset& dataset) {
  const Eigen::Vector4d* first = nullptr;
  Eigen::Vector4d q0;
  for (const Video& v : dataset.videos) {
    for (const Frame& f : v.frames) {
      if (f.skip) continue;
      const Eigen::Vector4d q = f.root_pose_init.segment<4>(kPoseQw).normalized();
      if (first == nullptr) {
        q0 = q;
        first = &q0;
        continue;
      }
      // Angle between the rotations: 2 acos |<q, q0>|.
      if (2 * std::acos(std::min(1.0, std::abs(q.dot(q0)))) > 1e-6) return true;
    }
  }
  return false;
}

RootRegistration RegisterRootPoseInit(const RootRegistrationOptions& options, Dataset* dataset) {
  RootRegistration result;
  std::vector<FrameRef> frames;
  if (!UsableFrames(*dataset, &frames, &result)) return result;
  const int nf = static_cast<int>(frames.size());
  std::mt19937_64 rng(kSeed);
  const Observations o = ObserveReferences(options, *dataset, frames, &rng);
  result.references = o.references;
  result.observations_per_frame = static_cast<double>(o.obs.size()) / nf;

  Factorisation best;
  for (int start = 0; start < kAlsStarts; ++start) {
    Factorisation f = Factorise(o.by_frame, o.by_point, o.obs, &rng);
    if (f.rms < best.rms) best = std::move(f);
  }
  if (!std::isfinite(best.rms)) {
    result.reason = "no frame has " + std::to_string(kMinFrameObservations) + " observations";
    return result;
  }
  // The factorisation's error in pixels (the first frame's focal length).
  result.affine_rms_px = best.rms * o.focal[0][0];

  // The adjustment and its mirror image side by side (each Ceres solve on
  // one thread; the same results as one after the other).
  Adjusted adjusted;
  Adjusted mirror;
  ParallelFor(2, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      (i == 0 ? adjusted : mirror) = Adjust(best, i == 1, o.obs, o.focal);
    }
  });
  if (mirror.cost < adjusted.cost) std::swap(adjusted, mirror);
  result.cost = adjusted.cost;
  result.mirror_cost = mirror.cost;
  result.median_residual_px = adjusted.median_px;
  result.iterations = adjusted.iterations;

  // Every video needs a registered frame.
  std::vector<std::vector<int>> registered(dataset->videos.size());
  for (int i = 0; i < nf; ++i) {
    if (best.frame_ok[i]) registered[frames[i].video].push_back(i);
  }
  for (size_t v = 0; v < registered.size(); ++v) {
    if (registered[v].empty() && !dataset->videos[v].frames.empty()) {
      result.reason = "no frame of video " + dataset->videos[v].name + " has " +
                      std::to_string(kMinFrameObservations) + " observations";
      return result;
    }
  }
  const VideoTracks tracks = MakeVideoTracks(*dataset, frames, registered, adjusted.poses);
  const bool any_kept = ChooseVideos(options, *dataset, tracks, &result);
  for (int i = 0; i < nf; ++i) result.frames += best.frame_ok[i] ? 1 : 0;
  Eigen::Matrix3d gauge;
  double scale = 1.0;
  if (!RegistrationGauge(frames, tracks, result, any_kept, &gauge, &scale)) {
    result.reason = "the videos kept have no registered frame to align the others to";
    return result;
  }
  for (int v = 0; v < static_cast<int>(dataset->videos.size()); ++v) {
    if (!result.videos[v].replaced) continue;
    Video& video = dataset->videos[v];
    for (int t = 0; t < static_cast<int>(video.frames.size()); ++t) {
      if (frames[tracks.source[v][t]].frame != t) ++result.filled;
      const Pose& p = tracks.registered[v][t];
      const Eigen::Quaterniond q(PoseRotation(p) * gauge);
      Pose& out = video.frames[t].root_pose_init;
      out << q.w(), q.x(), q.y(), q.z(), scale * p[kPoseT], scale * p[kPoseT + 1],
          scale * p[kPoseT + 2];
    }
  }
  result.registered = true;
  return result;
}

}  // namespace banmo
