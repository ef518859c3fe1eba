// Small fully connected networks whose weights are one external, contiguous
// double block (a Ceres parameter block), with
//   - a templated single-point forward (any scalar types, e.g. ceres::Jet for
//     inputs and/or weights): the exact, simple full-Jet reference path;
//   - batched double passes (column per sample, Eigen GEMM): forward, forward
//     tangents (input JVPs), reverse mode with per-group weight gradients
//     (one group = one ray's samples), and reverse mode of the tangent (the
//     eikonal term's weight gradient).
// See docs/design.md (mixed-mode derivatives).
//
// Architecture: hidden_layers hidden layers of `width` units with the chosen
// activation, then a linear output layer:
//   a_0 = input (input_dim)
//   z_l = W_l a_{l-1} + b_l,  a_l = act(z_l)      l = 1 .. hidden_layers
//   output = z_L = W_L a_{L-1} + b_L               L = hidden_layers + 1
// hidden_layers = 0 is a linear (affine) map.
//
// Parameter block layout (NumParameters() doubles): for each linear layer
// l = 1 .. L in order, W_l (out_l x in_l, row-major) followed by b_l (out_l).
//
// Threads: the batched passes split samples (or groups) over
// util/parallel.h ParallelFor; every output entry is written by one chunk, so
// results are deterministic for a fixed NumThreads() (a different thread
// count may change the last bits through GEMM blocking). All methods are
// const and safe to call concurrently on distinct outputs.
//
// Costs (tests/benchmarks: benchmarks/field/README.md): at width 64 and
// 32768 samples on 2 cores, ForwardBatch ~59 ms, Backward with 1024 per-ray
// gradients ~48 ms per call.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "banmo/util/enum_names.h"

namespace banmo {

enum class Activation {
  kSoftplus,  // (1/beta) log(1 + exp(beta z)), evaluated overflow-free
  kRelu,      // max(z, 0), derivative 0 at z = 0
};

template <>
struct EnumNames<Activation> {
  static constexpr std::pair<Activation, const char*> kNames[] = {
      {Activation::kSoftplus, "softplus"}, {Activation::kRelu, "relu"}};
};

struct MlpOptions {
  // Input dimension (> 0).
  int input_dim = 0;
  // Output dimension (> 0).
  int output_dim = 0;
  // Units per hidden layer (> 0).
  int width = 32;
  // Number of hidden (activated) layers (>= 0); there are hidden_layers + 1
  // linear layers.
  int hidden_layers = 3;
  // Hidden activation.
  Activation activation = Activation::kSoftplus;
  // Sharpness of the softplus (> 0); large beta approaches ReLU.
  double softplus_beta = 100.0;

  // Throws InputError naming the field under `key` unless the options are
  // valid.
  void Check(const std::string& key = "mlp") const;
};

// Activation functions shared by the templated and batched paths.
namespace mlp_internal {

// softplus_beta(z) = max(z, 0) + log1p(exp(-beta |z|)) / beta: never
// overflows (exp of a non-positive number), exact for both branches.
template <typename T>
inline T Softplus(const T& z, double beta) {
  using std::exp;
  using std::log1p;
  if (z > T(0.0)) return z + log1p(exp(-beta * z)) / beta;
  return log1p(exp(beta * z)) / beta;
}

template <typename T>
inline T Relu(const T& z) {
  if (z > T(0.0)) return z;
  return T(0.0);
}

}  // namespace mlp_internal

// Per-layer values of a batched forward pass (column per sample).
struct MlpCache {
  // a[0] = inputs (in x n); a[l] = act(z[l-1]) for l = 1 .. hidden_layers.
  std::vector<Eigen::MatrixXd> a;
  // z[l] = pre-activation of linear layer l+1 (out_{l+1} x n); z.back() is
  // the output.
  std::vector<Eigen::MatrixXd> z;
  // dact[l] = act'(z[l]) for the hidden layers l = 0 .. hidden_layers-1.
  std::vector<Eigen::MatrixXd> dact;
  int num_samples() const { return a.empty() ? 0 : static_cast<int>(a[0].cols()); }
};

class Mlp {
 public:
  explicit Mlp(const MlpOptions& options);

  const MlpOptions& options() const { return options_; }
  int InputDim() const { return options_.input_dim; }
  int OutputDim() const { return options_.output_dim; }
  int NumLinearLayers() const { return options_.hidden_layers + 1; }
  int NumParameters() const { return num_parameters_; }

  // Shape of linear layer l (0-based, l < NumLinearLayers()) and the offsets
  // of its weight matrix (row-major) and bias in the parameter block.
  int LayerInputDim(int l) const { return dims_[l]; }
  int LayerOutputDim(int l) const { return dims_[l + 1]; }
  int WeightOffset(int l) const { return weight_offset_[l]; }
  int BiasOffset(int l) const { return bias_offset_[l]; }

  // Deterministic default initialisation (params: NumParameters() doubles):
  // weights uniform in +-sqrt(6 / (fan_in + fan_out)) (Xavier/Glorot uniform)
  // from std::mt19937(seed), biases zero.
  void InitializeDefault(uint32_t seed, double* params) const;

  // Single point: output = MLP(input). T and P may be double or ceres::Jet;
  // T must hold products P * T (if P is a Jet, T is the same Jet type).
  template <typename T, typename P>
  void Forward(const P* params, const T* input, T* output) const;

  // Batched forward: inputs (in x n) -> outputs (out x n); fills cache (may
  // not be null) for the tangent / backward passes. Parallel over samples.
  void ForwardBatch(const double* params, const Eigen::MatrixXd& inputs, MlpCache* cache,
                    Eigen::MatrixXd* outputs) const;

  // Exact Jacobian-vector products at the cached points. input_tangents:
  // in x (k n), columns j*k .. j*k+k-1 are sample j's k tangents;
  // output_tangents: out x (k n), same layout.
  void ForwardTangents(const double* params, const MlpCache& cache,
                       const Eigen::MatrixXd& input_tangents, int k,
                       Eigen::MatrixXd* output_tangents) const;

  // Reverse mode at the cached points. d_outputs: out x n cotangents.
  // group_begin: size G+1, non-decreasing, group g = samples
  // [group_begin[g], group_begin[g+1]), group_begin.back() <= n (samples
  // outside all groups contribute to no column).
  // d_params (may be null): NumParameters x G, column g =
  //   sum_{j in g} (d out_j / d params)^T d_outputs_j.
  // d_inputs (may be null): in x n, column j = (d out_j / d in_j)^T d_outputs_j.
  void Backward(const double* params, const MlpCache& cache, const Eigen::MatrixXd& d_outputs,
                const std::vector<int>& group_begin, Eigen::MatrixXd* d_params,
                Eigen::MatrixXd* d_inputs) const;

  // Reverse mode of the tangent map. For samples with inputs x_j (cached),
  // input tangents v_j (input_tangents, in x n) and tangent cotangents c_j
  // (out x n), with S = sum_j c_j^T (d out / d x)(x_j) v_j:
  // d_params (may be null): NumParameters x G, column g = d S_g / d params
  //   (S_g = the sum over group g);
  // d_inputs (may be null): in x n, column j = d S / d x_j;
  // d_input_tangents (may be null): in x n, column j = d S / d v_j
  //   = (d out / d x)(x_j)^T c_j.
  void BackwardOfTangent(const double* params, const MlpCache& cache,
                         const Eigen::MatrixXd& input_tangents,
                         const Eigen::MatrixXd& tangent_cotangents,
                         const std::vector<int>& group_begin, Eigen::MatrixXd* d_params,
                         Eigen::MatrixXd* d_inputs, Eigen::MatrixXd* d_input_tangents) const;

 private:
  template <typename T>
  T Activate(const T& z) const {
    return options_.activation == Activation::kSoftplus
               ? mlp_internal::Softplus(z, options_.softplus_beta)
               : mlp_internal::Relu(z);
  }

  MlpOptions options_;
  std::vector<int> dims_;  // [in, width x hidden_layers, out]
  std::vector<int> weight_offset_;
  std::vector<int> bias_offset_;
  int num_parameters_ = 0;
  int max_dim_ = 0;
};

template <typename T, typename P>
void Mlp::Forward(const P* params, const T* input, T* output) const {
  std::vector<T> current(input, input + dims_[0]);
  std::vector<T> next;
  const int num_layers = NumLinearLayers();
  for (int l = 0; l < num_layers; ++l) {
    const int in = dims_[l];
    const int out = dims_[l + 1];
    const P* w = params + weight_offset_[l];
    const P* b = params + bias_offset_[l];
    next.assign(out, T(0.0));
    for (int o = 0; o < out; ++o) {
      T acc = T(b[o]);
      for (int i = 0; i < in; ++i) acc += w[o * in + i] * current[i];
      next[o] = (l + 1 < num_layers) ? Activate(acc) : acc;
    }
    current.swap(next);
  }
  for (int o = 0; o < dims_.back(); ++o) output[o] = current[o];
}

}  // namespace banmo
