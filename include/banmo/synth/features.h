// The synthetic stand-in for DensePose CSE pixel features: a fixed, smooth
// random embedding of the rest-pose (canonical) surface point.
//
// For a rest-pose point X (normalised rig coordinates: largest half-extent 1),
//   e_k(X) = sin(w_k . X + b_k),  k = 0..15,   feature = e / |e|,
// with w_k ~ N(0, sigma^2 I_3) (sigma = kFeatureFrequency rad/unit) and
// b_k ~ U[0, 2 pi), drawn once from std::mt19937_64 seeded with
// kFeatureEmbeddingSeed through the portable draws below (so the embedding is
// identical on every platform and for every scene, whatever --seed).
// Rendered features add i.i.d. N(0, noise^2) per channel and are
// renormalised to unit length.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>

#include "banmo/io/dataset.h"

namespace banmo::synth {

inline constexpr std::uint64_t kFeatureEmbeddingSeed = 20220601;
inline constexpr double kFeatureFrequency = 2.5;

using FeatureVector = Eigen::Matrix<double, kFeatureDim, 1>;

class FeatureEmbedding {
 public:
  FeatureEmbedding();
  // Unit-length feature of rest-pose point x.
  FeatureVector operator()(const Eigen::Vector3d& x) const;

 private:
  Eigen::Matrix<double, kFeatureDim, 3> w_;
  FeatureVector b_;
};

// Portable random draws (std::*_distribution differ between standard
// libraries): uniform in [0, 1) with 53 bits, standard normal by Box-Muller.
double UniformDraw(std::mt19937_64& rng);
double NormalDraw(std::mt19937_64& rng);

// Seed for an independent stream from a base seed and up to three indices
// (SplitMix64 mixing).
std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0,
                      std::uint64_t c = 0);

}  // namespace banmo::synth
