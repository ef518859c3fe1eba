#include "banmo/synth/animation.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "banmo/util/logging.h"

namespace banmo::synth {

int ChannelComponents(ChannelPath path, int num_morph_targets) {
  switch (path) {
    case ChannelPath::kTranslation:
    case ChannelPath::kScale:
      return 3;
    case ChannelPath::kRotation:
      return 4;
    case ChannelPath::kWeights:
      return num_morph_targets;
  }
  return 0;
}

std::string AnimationChannel::Validate() const {
  std::ostringstream os;
  if (times.empty()) return "channel has no keys";
  for (size_t i = 0; i < times.size(); ++i) {
    if (!std::isfinite(times[i])) return "key time is not finite";
    if (i > 0 && !(times[i] > times[i - 1])) {
      os << "key times are not strictly increasing at key " << i;
      return os.str();
    }
  }
  const int per_key = interpolation == Interpolation::kCubicSpline ? 3 : 1;
  if (values.cols() != per_key * NumKeys()) {
    os << "expected " << per_key * NumKeys() << " output values for " << NumKeys()
       << " keys, found " << values.cols();
    return os.str();
  }
  if (path == ChannelPath::kRotation && values.rows() != 4)
    return "rotation values need 4 components";
  if ((path == ChannelPath::kTranslation || path == ChannelPath::kScale) && values.rows() != 3) {
    return "translation/scale values need 3 components";
  }
  if (!values.allFinite()) return "output values are not finite";
  return "";
}

namespace {

// Value column of key k (skipping tangents for CUBICSPLINE).
Eigen::VectorXd KeyValue(const AnimationChannel& c, int k) {
  return c.interpolation == Interpolation::kCubicSpline ? c.values.col(3 * k + 1) : c.values.col(k);
}

Eigen::VectorXd NormalizedIfRotation(const AnimationChannel& c, Eigen::VectorXd v) {
  if (c.path == ChannelPath::kRotation) {
    const double n = v.norm();
    if (n > 0) v /= n;
  }
  return v;
}

}  // namespace

Eigen::VectorXd SampleChannel(const AnimationChannel& c, double t) {
  CHECK(!c.times.empty());
  const int n = c.NumKeys();
  if (n == 1 || t <= c.times.front()) return NormalizedIfRotation(c, KeyValue(c, 0));
  if (t >= c.times.back()) return NormalizedIfRotation(c, KeyValue(c, n - 1));
  // Key interval [k, k + 1] with times[k] <= t < times[k + 1].
  const int k =
      static_cast<int>(std::upper_bound(c.times.begin(), c.times.end(), t) - c.times.begin()) - 1;
  const double dt = c.times[k + 1] - c.times[k];
  const double s = (t - c.times[k]) / dt;
  switch (c.interpolation) {
    case Interpolation::kStep:
      return NormalizedIfRotation(c, c.values.col(k));
    case Interpolation::kLinear: {
      if (c.path == ChannelPath::kRotation) {
        // glTF stores [x, y, z, w]; Eigen's constructor takes (w, x, y, z).
        const Eigen::Vector4d a = c.values.col(k), b = c.values.col(k + 1);
        const Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
        // Eigen's slerp takes the shortest arc (flips qb when qa.qb < 0).
        const Eigen::Quaterniond q = qa.normalized().slerp(s, qb.normalized());
        Eigen::VectorXd out(4);
        out << q.x(), q.y(), q.z(), q.w();
        return out;
      }
      return (1 - s) * c.values.col(k) + s * c.values.col(k + 1);
    }
    case Interpolation::kCubicSpline: {
      const double s2 = s * s, s3 = s2 * s;
      const Eigen::VectorXd v0 = c.values.col(3 * k + 1);
      const Eigen::VectorXd b0 = c.values.col(3 * k + 2);  // out-tangent of key k
      const Eigen::VectorXd v1 = c.values.col(3 * (k + 1) + 1);
      const Eigen::VectorXd a1 = c.values.col(3 * (k + 1));  // in-tangent of key k + 1
      Eigen::VectorXd p = (2 * s3 - 3 * s2 + 1) * v0 + (s3 - 2 * s2 + s) * dt * b0 +
                          (-2 * s3 + 3 * s2) * v1 + (s3 - s2) * dt * a1;
      return NormalizedIfRotation(c, p);
    }
  }
  return KeyValue(c, 0);
}

double Animation::StartTime() const {
  if (channels.empty()) return 0;
  double t = std::numeric_limits<double>::infinity();
  for (const auto& c : channels) t = std::min(t, c.times.front());
  return t;
}

double Animation::EndTime() const {
  if (channels.empty()) return 0;
  double t = -std::numeric_limits<double>::infinity();
  for (const auto& c : channels) t = std::max(t, c.times.back());
  return t;
}

double Animation::WrapTime(double t) const {
  const double start = StartTime(), duration = Duration();
  if (!(duration > 0)) return start;
  double r = std::fmod(t - start, duration);
  if (r < 0) r += duration;
  return start + r;
}

}  // namespace banmo::synth
