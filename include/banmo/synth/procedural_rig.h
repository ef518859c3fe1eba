// Procedural creatures: a rig built from a small YAML definition
// (data/rigs/*.yaml, documented in docs/synth.md).
//
// The surface is the zero level set of a smooth union (polynomial smooth
// minimum) of ellipsoids and capsules, each attached to a joint, meshed with
// surface nets on a regular grid and projected onto the level set. Skin
// weights fall off smoothly with the distance to each joint's shapes:
//   w_j(x) ~ exp(-(d_j(x) - min_k d_k(x)) / skin_blend),
// keeping the 4 largest, normalised. Vertex colours blend the shapes' base
// colours with the same kind of weights, modulated by a smooth sinusoidal
// pattern over the rest position (so photometric losses have texture to use).
// The animation is a sum of sinusoids per joint (rotation about an axis,
// translation), sampled into LINEAR channels with `keys` keys per clip.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>

#include "banmo/synth/rig.h"

namespace banmo::synth {

// Builds the rig described by `yaml_text`; `source` (a file name or
// "builtin:<name>") is used in error messages. Throws InputError naming the
// source and key for unknown keys, missing keys or bad values.
Rig BuildProceduralRig(const std::string& yaml_text, const std::string& source);

// Surface nets on a grid: the zero level set of `sdf` (negative inside)
// within [lo, hi], with cells of about `cell_size`. Vertices are projected
// onto the level set with `projection_steps` Newton steps (numerical
// gradient). Faces are oriented counter-clockwise seen from outside.
TriangleMesh MeshLevelSet(const std::function<double(const Eigen::Vector3d&)>& sdf,
                          const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double cell_size,
                          int projection_steps = 2);

// Signed distance (approximate for ellipsoids: the k0 (k0 - 1) / k1 bound)
// to an axis-aligned ellipsoid centred at the origin, and exact to a capsule.
double EllipsoidSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& radii);
double CapsuleSdf(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                  double radius);
// Polynomial smooth minimum with blend radius k (k = 0: plain min).
double SmoothMin(double a, double b, double k);

}  // namespace banmo::synth
