#include "banmo/synth/features.h"

#include <cmath>

namespace banmo::synth {

double UniformDraw(std::mt19937_64& rng) { return (rng() >> 11) * 0x1.0p-53; }

double NormalDraw(std::mt19937_64& rng) {
  const double u1 = 1.0 - UniformDraw(rng);  // (0, 1]
  const double u2 = UniformDraw(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2 * M_PI * u2);
}

std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t a, std::uint64_t b, std::uint64_t c) {
  auto splitmix = [](std::uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
  };
  std::uint64_t h = splitmix(seed);
  h = splitmix(h ^ a);
  h = splitmix(h ^ b);
  h = splitmix(h ^ c);
  return h;
}

FeatureEmbedding::FeatureEmbedding() {
  std::mt19937_64 rng(kFeatureEmbeddingSeed);
  for (int k = 0; k < kFeatureDim; ++k) {
    for (int a = 0; a < 3; ++a) w_(k, a) = kFeatureFrequency * NormalDraw(rng);
    b_[k] = 2 * M_PI * UniformDraw(rng);
  }
}

FeatureVector FeatureEmbedding::operator()(const Eigen::Vector3d& x) const {
  FeatureVector e = (w_ * x + b_).array().sin().matrix();
  const double n = e.norm();
  return n > 0 ? FeatureVector(e / n) : e;
}

}  // namespace banmo::synth
