// Delta skinning weights (BANMo, Yang et al. CVPR 2022, Sec. 3.2, Eq. 14):
//   W = softmax(W_sigma + W_Delta),  W_Delta = MLP_Delta(X, omega) in R^B,
// a coordinate MLP of a point X and a body-pose code omega that adds
// point-specific logits to the Gaussian bones' logits (bones.h), "after the
// coarse component is well-optimized".
//
// Which point and code (as the paper): the backward warp of frame t
// evaluates MLP_Delta at the time-t point x (root frame) with the frame's
// pose code omega^t; every forward warp evaluates it at the canonical point
// X* with the rest-pose code omega^*, so forward skinning weights do not
// depend on the target frame (and stay exportable as linear blend skinning).
//
// Network input: [PE(X), omega] (PE = field/encoding.h without annealing),
// output B logits. Initialisation: Xavier for the hidden layers, the output
// layer ZERO, so W_Delta == 0 until the output layer is trained: switching
// delta skinning on mid-run does not move the model (IsZero tells whether a
// parameter block is still in that state).
//
// Parameter blocks: the MLP weights (NumParameters()), the rest-pose code
// (CodeDim()) and one pose code per frame (CodeDim()).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "banmo/field/encoding.h"
#include "banmo/field/mlp.h"

namespace banmo {

struct DeltaSkinningOptions {
  // Whether the model has the delta-skinning MLP and pose codes at all.
  bool enabled = false;
  // Units per hidden layer (> 0).
  int width = 32;
  // Hidden layers (>= 1).
  int hidden_layers = 2;
  // Positional-encoding bands of X (>= 0; the raw X is always included).
  int num_bands = 4;
  // Dimension of the pose codes omega (>= 1).
  int pose_code_dim = 8;
  // Standard deviation of the initial pose codes (>= 0): small random codes
  // let frames differ as soon as the output layer moves.
  double code_init_std = 0.1;

  // Throws InputError naming the field (prefix "model.delta_skinning.").
  void Check() const;
};

// A batched MLP_Delta pass: the inputs and the MLP's cached layers.
struct DeltaSkinningBatch {
  Eigen::Matrix3Xd x;      // points (3 x n)
  Eigen::MatrixXd codes;   // pose codes (CodeDim x n)
  Eigen::MatrixXd logits;  // W_Delta (B x n)
  // d logits / d [x, code] (B x (3 + CodeDim) n): block j (columns
  // (3 + P) j ..) = sample j's Jacobian; filled when asked for.
  Eigen::MatrixXd jacobian;
  MlpCache cache;
};

class DeltaSkinning {
 public:
  DeltaSkinning(const DeltaSkinningOptions& options, int num_bones);

  const DeltaSkinningOptions& options() const { return options_; }
  int num_bones() const { return num_bones_; }
  int CodeDim() const { return options_.pose_code_dim; }
  // 3 + CodeDim: the local variables of one evaluation.
  int LocalDim() const { return 3 + options_.pose_code_dim; }
  int NumParameters() const { return mlp_.NumParameters(); }
  const Mlp& mlp() const { return mlp_; }

  // Xavier hidden layers from `seed`, output layer zero.
  void InitializeParameters(uint32_t seed, double* params) const;
  // True when the output layer is all zeros (then W_Delta == 0 everywhere).
  bool IsZero(const double* params) const;

  // Single point, any scalar types (reference path): out = B logits.
  template <typename T, typename P>
  void Logits(const P* params, const T* x, const T* code, T* out) const;

  // Batched forward of batch->x and batch->codes; with `jacobian`, also
  // batch->jacobian.
  void ForwardBatch(const double* params, DeltaSkinningBatch* batch, bool jacobian) const;

  // d_params (NumParameters x G): column g = sum over samples j of group g of
  // (d logits_j / d params)^T d_logits_j (group_begin as Mlp::Backward).
  void BackwardBatch(const double* params, const DeltaSkinningBatch& batch,
                     const Eigen::MatrixXd& d_logits, const std::vector<int>& group_begin,
                     Eigen::MatrixXd* d_params) const;

 private:
  DeltaSkinningOptions options_;
  int num_bones_;
  PositionalEncoding encoding_;
  Mlp mlp_;
};

template <typename T, typename P>
void DeltaSkinning::Logits(const P* params, const T* x, const T* code, T* out) const {
  const int pe = encoding_.OutputDim();
  std::vector<T> input(pe + CodeDim());
  encoding_.Encode(x, input.data());
  for (int k = 0; k < CodeDim(); ++k) input[pe + k] = code[k];
  mlp_.Forward(params, input.data(), out);
}

}  // namespace banmo
