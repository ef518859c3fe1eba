#include "banmo/registration/root_init_smoothing.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <cmath>

#include "banmo/util/logging.h"
#include "banmo/util/median.h"

namespace banmo {
namespace {

constexpr double kRadPerDeg = M_PI / 180.0;
// The median of |x| for x ~ N(0, I_3): the square root of chi^2_3's median
// (2.3660).
constexpr double kChi3MedianNorm = 1.5382;
// The noise estimate's floor (rad): a constant track (identity poses) has
// none, and its data term must stay finite.
constexpr double kMinNoise = 1e-4;

// q0 * Exp(d) (object-side rotation vector d), Ceres' [w, x, y, z] order.
template <typename T>
void Perturbed(const double* q0, const T* d, T* q) {
  T e[4];
  ceres::AngleAxisToQuaternion(d, e);
  const T a[4] = {T(q0[0]), T(q0[1]), T(q0[2]), T(q0[3])};
  ceres::QuaternionProduct(a, e, q);
}

// Log(Ra^T Rb) as a rotation vector; the shorter of q and -q
// (ceres::QuaternionToAngleAxis returns angles in [-pi, pi]).
template <typename T>
void Relative(const T* qa, const T* qb, T* v) {
  const T conj[4] = {qa[0], -qa[1], -qa[2], -qa[3]};
  T r[4];
  ceres::QuaternionProduct(conj, qb, r);
  ceres::QuaternionToAngleAxis(r, v);
}

// A frame's data term: its correction d in units of the noise.
struct TrackData {
  explicit TrackData(double inv_sigma) : inv_sigma(inv_sigma) {}
  template <typename T>
  bool operator()(const T* d, T* r) const {
    for (int k = 0; k < 3; ++k) r[k] = d[k] * inv_sigma;
    return true;
  }
  double inv_sigma;
};

// The prior: the second difference of the rotation track at frames
// (t-1, t, t+1), in units of the expected acceleration.
struct TrackAcceleration {
  TrackAcceleration(const double* qa, const double* qb, const double* qc, double inv_accel)
      : inv_accel(inv_accel) {
    std::copy(qa, qa + 4, this->qa);
    std::copy(qb, qb + 4, this->qb);
    std::copy(qc, qc + 4, this->qc);
  }
  template <typename T>
  bool operator()(const T* da, const T* db, const T* dc, T* r) const {
    T a[4], b[4], c[4], v0[3], v1[3];
    Perturbed(qa, da, a);
    Perturbed(qb, db, b);
    Perturbed(qc, dc, c);
    Relative(a, b, v0);
    Relative(b, c, v1);
    for (int k = 0; k < 3; ++k) r[k] = (v1[k] - v0[k]) * inv_accel;
    return true;
  }
  double qa[4], qb[4], qc[4];
  double inv_accel;
};

Eigen::Vector4d UnitQuaternion(const Pose& p) { return p.segment<4>(kPoseQw).normalized(); }

// Log(a^-1 b) of two unit quaternions in Ceres' order, the shorter way round.
Eigen::Vector3d LogRelative(const Eigen::Vector4d& a, const Eigen::Vector4d& b) {
  Eigen::Vector3d v;
  Relative(a.data(), b.data(), v.data());
  return v;
}

// The geometric median (L1 mean) of the rotations q0[lo..hi] by Weiszfeld's
// iteration in the tangent space at the current estimate, started at q0[t]:
// a few frames far off do not drag it as an average would. Weights
// 1 / max(|d|, 1e-3 rad); 30 iterations.
Eigen::Vector4d WindowMedian(const std::vector<Eigen::Vector4d>& q0, int t, int lo, int hi) {
  Eigen::Vector4d r = q0[t];
  for (int it = 0; it < 30; ++it) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double weights = 0.0;
    for (int k = lo; k <= hi; ++k) {
      const Eigen::Vector3d d = LogRelative(r, q0[k]);
      const double w = 1.0 / std::max(d.norm(), 1e-3);
      sum += w * d;
      weights += w;
    }
    const Eigen::Vector3d step = sum / weights;
    Eigen::Vector4d moved;
    Perturbed(r.data(), step.data(), moved.data());
    r = moved.normalized();
  }
  return r;
}

// The noise of a rotation track (radians, at least 3 rotations) from its
// second differences: for i.i.d. per-axis noise N(0, sigma^2) each axis of
// v_t - v_{t-1} has variance 6 sigma^2 (to first order), so |.| has median
// sqrt(6) 1.538 sigma. Also returns the largest second difference.
double TrackNoise(const std::vector<Eigen::Vector4d>& q0, double* max_accel) {
  std::vector<double> accel;
  const double zero[3] = {0, 0, 0};
  const int n = static_cast<int>(q0.size());
  for (int t = 1; t + 1 < n; ++t) {
    const TrackAcceleration f(q0[t - 1].data(), q0[t].data(), q0[t + 1].data(), 1.0);
    Eigen::Vector3d r;
    f(zero, zero, zero, r.data());
    accel.push_back(r.norm());
  }
  *max_accel = *std::max_element(accel.begin(), accel.end());
  return Median(std::move(accel)) / (std::sqrt(6.0) * kChi3MedianNorm);
}

}  // namespace

double RootTrackNoiseDeg(const std::vector<Pose>& poses) {
  if (poses.size() < 3) return 0.0;
  std::vector<Eigen::Vector4d> q(poses.size());
  for (size_t t = 0; t < poses.size(); ++t) q[t] = UnitQuaternion(poses[t]);
  double max_accel = 0.0;
  return TrackNoise(q, &max_accel) / kRadPerDeg;
}

RootTrackSmoothing SmoothRootTrack(const RootSmoothingOptions& options, std::vector<Pose>* poses,
                                   const std::vector<bool>& observed) {
  CHECK(options.acceleration_deg > 0 && options.robust_sigmas > 0);
  RootTrackSmoothing out;
  const int n = static_cast<int>(poses->size());
  CHECK(observed.empty() || static_cast<int>(observed.size()) == n);
  if (n < 3) return out;
  std::vector<Eigen::Vector4d> q0(n);
  for (int t = 0; t < n; ++t) q0[t] = UnitQuaternion((*poses)[t]);

  double max_accel = 0.0;
  const double sigma = std::max(kMinNoise, TrackNoise(q0, &max_accel));
  out.noise_deg = sigma / kRadPerDeg;
  out.max_acceleration_deg = max_accel / kRadPerDeg;
  // A track already as smooth as the prior expects (no second difference
  // above `acceleration_deg`) shows no error to remove: it is left exactly
  // as it is, so exact poses give the same solve as without the smoothing
  // (the synthetic scenes' exact tracks: at most 1.0-1.6 deg). One frame
  // off is enough to smooth the track.
  if (max_accel <= options.acceleration_deg * kRadPerDeg) return out;
  out.smoothed = true;

  // The solve starts from a running median of the rough track (window of
  // 2 kMedianHalfWidth + 1 frames): from the rough poses themselves, each
  // frame sits in a minimum of its own robust data term, and tracks with
  // errors of 90 deg and more stay there (on `quad` with Gaussian noise of
  // mean 90 deg: 79 deg mean error left from the rough poses, 46 from the
  // running median; at 50 deg both give 17). A track exact but for a few
  // frames returns to its poses: its data term is the stiff one.
  constexpr int kMedianHalfWidth = 3;
  std::vector<Eigen::Vector3d> d(n);
  for (int t = 0; t < n; ++t) {
    const Eigen::Vector4d m = WindowMedian(q0, t, std::max(0, t - kMedianHalfWidth),
                                           std::min(n - 1, t + kMedianHalfWidth));
    d[t] = LogRelative(q0[t], m);
  }
  ceres::Problem problem;
  for (int t = 0; t < n; ++t) {
    if (!observed.empty() && !observed[t]) {
      problem.AddParameterBlock(d[t].data(), 3);  // placed by the prior alone
      continue;
    }
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<TrackData, 3, 3>(new TrackData(1.0 / sigma)),
        new ceres::CauchyLoss(options.robust_sigmas), d[t].data());
  }
  const double inv_accel = 1.0 / (options.acceleration_deg * kRadPerDeg);
  for (int t = 1; t + 1 < n; ++t) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<TrackAcceleration, 3, 3, 3, 3>(
            new TrackAcceleration(q0[t - 1].data(), q0[t].data(), q0[t + 1].data(), inv_accel)),
        nullptr, d[t - 1].data(), d[t].data(), d[t + 1].data());
  }
  ceres::Solver::Options so;
  // Banded normal equations (each frame couples to its two neighbours on
  // either side); Eigen's sparse Cholesky is always available.
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  so.max_num_iterations = 100;
  so.function_tolerance = 1e-10;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  CHECK(summary.IsSolutionUsable()) << summary.BriefReport();
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;

  double total = 0.0;
  for (int t = 0; t < n; ++t) {
    Eigen::Vector4d q;
    Perturbed(q0[t].data(), d[t].data(), q.data());
    q.normalize();
    (*poses)[t].segment<4>(kPoseQw) = q;
    // The angle of Exp(d_t), in [0, 180] deg (|d_t| may exceed pi).
    const double change = LogRelative(q0[t], q).norm() / kRadPerDeg;
    total += change;
    out.max_change_deg = std::max(out.max_change_deg, change);
  }
  out.mean_change_deg = total / n;
  return out;
}

std::vector<RootTrackSmoothing> SmoothRootPoseInit(const RootSmoothingOptions& options,
                                                   Dataset* dataset) {
  std::vector<RootTrackSmoothing> out;
  for (Video& video : dataset->videos) {
    std::vector<Pose> track;
    std::vector<bool> observed;
    for (const Frame& f : video.frames) {
      track.push_back(f.root_pose_init);
      observed.push_back(!f.held_out);
    }
    out.push_back(SmoothRootTrack(options, &track, observed));
    for (size_t t = 0; t < video.frames.size(); ++t) video.frames[t].root_pose_init = track[t];
  }
  return out;
}

}  // namespace banmo
