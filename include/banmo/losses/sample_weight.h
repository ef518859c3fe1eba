// The smallest rendering weight a ray sample needs to enter the sums that
// forward-warp it, the 3D cycle (Cycle3dLoss) and the rendered flow, and
// the rendered colour (RayCompositeFunctor). A sample of weight tau_i <
// kMinWarpTau carries less than 1e-4 of its ray's colour; its share of
// those terms, and of their derivatives (which scale with tau_i, or tau_i /
// beta through the density), is as small. Most samples of a ray lie in
// empty space or behind the surface, and the ray pipeline skips their
// forward warps and their colour MLP (docs/solver.md, "Samples of
// negligible weight").
#pragma once

#include <ceres/jet.h>

namespace banmo {

inline constexpr double kMinWarpTau = 1e-4;

// Whether a weight (a double or the value of a Jet) reaches kMinWarpTau.
inline bool WarpsSample(double tau) { return tau >= kMinWarpTau; }
template <typename T, int N>
bool WarpsSample(const ceres::Jet<T, N>& tau) {
  return WarpsSample(tau.a);
}

}  // namespace banmo
