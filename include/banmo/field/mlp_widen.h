// Function-preserving widening of an Mlp (Net2WiderNet: Chen, Goodfellow and
// Shlens, "Net2Net: Accelerating Learning via Knowledge Transfer", ICLR 2016,
// Sec. 2.1), used by automatic model sizing (optim/auto_size.h).
//
// Every hidden layer l grows from `width` to `new_width` units by a map
// g_l: {0 .. new_width-1} -> {0 .. width-1} with g_l(j) = j for the old units
// and g_l(j) drawn uniformly for the new ones. Unit j copies unit g_l(j)'s
// incoming weights and bias; the outgoing weights of an old unit k are
// divided among its c_k replicas (itself included), each getting 1 / c_k:
//   W'_l[j, i] = W_l[g_l(j), g_{l-1}(i)] / c_{g_{l-1}(i)}    (l >= 2; layer 1
//                                                             keeps its inputs)
//   b'_l[j]    = b_l[g_l(j)]
// and the output layer keeps its rows. By induction every replica of unit k
// has the activation of unit k, and the next layer sums
// sum_{i: g(i) = k} W[., k] / c_k a_k = W[., k] a_k: the same outputs, up
// to rounding, for any activation.
//
// Symmetry: replicas have identical incoming weights and equal outgoing
// weights, so they receive identical (Adam: identically normalised) updates
// and would stay copies forever. `incoming_noise` > 0 multiplies the
// incoming weights and bias of the NEW units by (1 + incoming_noise * u),
// u uniform in [-1, 1] (the paper's "small noise"); the function then moves
// by about incoming_noise times those units' share of it. 0 = exact.
#pragma once

#include <random>
#include <vector>

#include "banmo/field/mlp.h"

namespace banmo {

struct MlpWidening {
  MlpOptions options;          // the widened network's options (width = new_width)
  std::vector<double> params;  // its parameters (layout of mlp.h)
  // For each new parameter k: the old parameter it derives from, and the
  // factor that relates the gradients at the widening point:
  // d loss / d params[k] = gradient_scale[k] * d loss / d old[source[k]]
  // (1 / c of the parameter's own unit for the incoming weights and bias of
  // a hidden unit, 1 for the output layer). Used to carry optimiser moments
  // over (Adam: m' = s m, v' = s^2 v).
  std::vector<int> source;
  std::vector<double> gradient_scale;
  // Per hidden layer, g_l (size new_width).
  std::vector<std::vector<int>> unit_source;
};

// Widens `mlp` (parameters `params`) to `new_width` >= mlp.options().width
// hidden units per layer. Draws the new units' sources (and noise) from
// `rng`; deterministic for a given rng state. With hidden_layers = 0 or
// new_width == width the parameters are copied unchanged.
MlpWidening WidenMlp(const Mlp& mlp, const double* params, int new_width, double incoming_noise,
                     std::mt19937* rng);

}  // namespace banmo
