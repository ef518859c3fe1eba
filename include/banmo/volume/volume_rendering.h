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
//
// Density kNeus (NeuS, Wang et al. NeurIPS 2021, Eq. 13, with its s = 1 /
// beta): the opacity of the interval between samples i and i + 1 is
//   alpha_i = max((Phi(f_i) - Phi(f_{i+1})) / Phi(f_i), 0),
// Phi(f) = sigmoid(f / beta), so its "optical depth" -log(1 - alpha_i) is
//   max(log Phi(f_i) - log Phi(f_{i+1}), 0),  log Phi(f) = -softplus(-f / beta),
// and the last sample (no successor) gets none. A ray along which the SDF
// falls from f_0 to a minimum f_min and rises again has opacity
// 1 - Phi(f_min) / Phi(f_0): 1/2 for a ray that grazes the zero level set
// (f_0 >> beta), whatever the surface's curvature, so the silhouette a
// silhouette loss fits is the zero level set's. With VolSDF's density it lies
// outside the zero level set by about 1 to 2 beta for radii of curvature
// of 2 to 20 beta (a grazing ray gathers density along its whole path
// through the shell: beta ln(sqrt(2 pi R / beta) / (2 ln 2)) to first order).
#pragma once

#include <ceres/jet.h>

#include <cmath>
#include <random>
#include <vector>

#include "banmo/volume/density_model.h"

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

// log Phi(f) = log sigmoid(f / beta) = -softplus(-f / beta), in a form whose
// exponent is never positive.
template <typename T>
inline T LogSigmoidOfSdf(const T& sdf, const T& log_beta) {
  using std::exp;
  using std::log1p;
  const T x = sdf * exp(-log_beta);
  return x >= T(0) ? -log1p(exp(-x)) : x - log1p(exp(x));
}

// tau (N) from per-sample SDF values; deltas are constants (distances;
// unused by kNeus, whose intervals are the samples' spacing).
template <typename T>
inline void CompositeWeights(int num_samples, const T* sdf, const T& log_beta, const double* deltas,
                             DensityModel density, T* tau) {
  using std::exp;
  using std::expm1;
  T log_transmittance(0);
  T log_phi_next =
      num_samples > 0 && density == DensityModel::kNeus ? LogSigmoidOfSdf(sdf[0], log_beta) : T(0);
  for (int i = 0; i < num_samples; ++i) {
    T optical_depth(0);
    if (density == DensityModel::kVolSdf) {
      optical_depth = LaplaceDensity(sdf[i], log_beta) * deltas[i];
    } else if (i + 1 < num_samples) {
      const T log_phi = log_phi_next;
      log_phi_next = LogSigmoidOfSdf(sdf[i + 1], log_beta);
      const T drop = log_phi - log_phi_next;
      if (drop > T(0)) optical_depth = drop;
    }
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
