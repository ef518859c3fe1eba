// Volume rendering of a ray through an SDF (BANMo, Yang et al. CVPR 2022,
// Sec. 3.1, Eqs. 2, 4-5; density of VolSDF, Yariv et al. NeurIPS 2021),
// templated for Jets.
//
// Density (Eq. 2, Gamma_beta = VolSDF's Laplace CDF):
//   sigma(s) = (1 / beta) Psi_beta(-s),
//   Psi_beta(x) = 1/2 exp(x / beta)        for x <= 0,
//               = 1 - 1/2 exp(-x / beta)   for x >  0,
// evaluated so that the exponent is never positive: no overflow for tiny
// beta (1e-4), no log(0) anywhere.
// Transmittance in log space (Eq. 4): with p_i = exp(-sigma_i delta_i),
//   log T_i = sum_{j<i} -sigma_j delta_j,
//   tau_i   = T_i (1 - p_i) = exp(log T_i) * (-expm1(-sigma_i delta_i)).
// delta_i is the distance (scene units along the ray) of sample i's interval.
#pragma once

#include <ceres/jet.h>

#include <cmath>
#include <random>
#include <vector>

namespace banmo {

// beta is parameterised by its logarithm (one parameter block of size 1) so it
// stays positive under any step.
template <typename T>
inline T LaplaceDensity(const T& sdf, const T& log_beta) {
  using std::exp;
  const T inv_beta = exp(-log_beta);
  const T x = -sdf * inv_beta;  // Psi's argument divided by beta
  T psi;
  if (x <= T(0)) {
    psi = T(0.5) * exp(x);
  } else {
    psi = T(1) - T(0.5) * exp(-x);
  }
  return inv_beta * psi;
}

// tau (N) from per-sample SDF values; deltas are constants (distances).
template <typename T>
inline void CompositeWeights(int num_samples, const T* sdf, const T& log_beta, const double* deltas,
                             T* tau) {
  using std::exp;
  using std::expm1;
  T log_transmittance(0);
  for (int i = 0; i < num_samples; ++i) {
    const T optical_depth = LaplaceDensity(sdf[i], log_beta) * deltas[i];
    tau[i] = exp(log_transmittance) * (-expm1(-optical_depth));
    log_transmittance -= optical_depth;
  }
}

// Stratified sample depths along a ray: sample i is uniform in the i-th of N
// equal bins of [near, far] (or at the bin centre when `jitter` is false).
// depths are camera z values; deltas are the distances along the ray
// between consecutive samples (the last one reaches `far`), i.e. z
// differences times the ray direction's length `dir_norm` (direction with
// z = 1, camera.h).
struct RaySamples {
  std::vector<double> depths;
  std::vector<double> deltas;
  double dir_norm = 1.0;  // length of the ray direction with z = 1
};
RaySamples StratifiedSamples(int num_samples, double near, double far, double dir_norm, bool jitter,
                             std::mt19937* rng);

}  // namespace banmo
