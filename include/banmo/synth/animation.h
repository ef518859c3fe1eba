// Keyframe animation channels in the glTF 2.0 model (spec section 3.11):
// a channel drives one property (translation, rotation, scale or morph
// weights) of one node through a sampler with LINEAR, STEP or CUBICSPLINE
// interpolation. Procedural rigs produce the same channels, so one sampler
// serves both.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace banmo::synth {

enum class Interpolation { kLinear, kStep, kCubicSpline };
enum class ChannelPath { kTranslation, kRotation, kScale, kWeights };

// Number of components of one value of `path` (rotation: quaternion
// [x, y, z, w] as in glTF; weights: the number of morph targets).
int ChannelComponents(ChannelPath path, int num_morph_targets = 0);

struct AnimationChannel {
  int node = -1;  // index into Rig::nodes
  ChannelPath path = ChannelPath::kTranslation;
  Interpolation interpolation = Interpolation::kLinear;
  // Key times in seconds, strictly increasing.
  std::vector<double> times;
  // One column per output element. LINEAR/STEP: one column per key.
  // CUBICSPLINE: three columns per key, in glTF order
  // (in-tangent a_k, value v_k, out-tangent b_k). Rotations are quaternions
  // stored [x, y, z, w] (glTF order).
  Eigen::MatrixXd values;

  int NumKeys() const { return static_cast<int>(times.size()); }
  // Checks sizes and monotonic times; returns an empty string when valid,
  // otherwise what is wrong.
  std::string Validate() const;
};

// Value of `channel` at time t (seconds). Outside [t_0, t_last] the first or
// last key value is held (glTF clamps). LINEAR rotations use spherical
// linear interpolation along the shortest arc; CUBICSPLINE follows the glTF
// Hermite formula with tangents scaled by the key interval
//   p(s) = (2s^3-3s^2+1) v_k + (s^3-2s^2+s) dt b_k + (-2s^3+3s^2) v_k+1 + (s^3-s^2) dt a_k+1,
// and rotations (any mode) are renormalised to unit length.
Eigen::VectorXd SampleChannel(const AnimationChannel& channel, double t);

struct Animation {
  std::string name;
  std::vector<AnimationChannel> channels;

  // First and last key time over all channels (0, 0 when empty).
  double StartTime() const;
  double EndTime() const;
  double Duration() const { return EndTime() - StartTime(); }
  // Maps any time onto the clip, looping: start + (t - start) mod duration.
  double WrapTime(double t) const;
};

}  // namespace banmo::synth
