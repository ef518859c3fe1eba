#include "banmo/deform/delta_skinning.h"

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {
namespace {

PositionalEncodingOptions EncodingOptions(const DeltaSkinningOptions& o) {
  PositionalEncodingOptions e;
  e.num_bands = o.num_bands;
  e.include_input = true;
  return e;
}

MlpOptions NetworkOptions(const DeltaSkinningOptions& o, int num_bones) {
  MlpOptions m;
  m.input_dim = PositionalEncoding(EncodingOptions(o)).OutputDim() + o.pose_code_dim;
  m.output_dim = num_bones;
  m.width = o.width;
  m.hidden_layers = o.hidden_layers;
  return m;
}

}  // namespace

void DeltaSkinningOptions::Check() const {
  if (width < 1) ThrowInputError("model.delta_skinning.width: expected >= 1, got ", width);
  if (hidden_layers < 1) {
    ThrowInputError("model.delta_skinning.hidden_layers: expected >= 1, got ", hidden_layers);
  }
  if (num_bands < 0 || num_bands > 16) {
    ThrowInputError("model.delta_skinning.num_bands: expected 0..16, got ", num_bands);
  }
  if (pose_code_dim < 1 || pose_code_dim > 256) {
    ThrowInputError("model.delta_skinning.pose_code_dim: expected 1..256, got ", pose_code_dim);
  }
  if (!(code_init_std >= 0.0) || !std::isfinite(code_init_std)) {
    ThrowInputError("model.delta_skinning.code_init_std: expected a finite value >= 0");
  }
}

DeltaSkinning::DeltaSkinning(const DeltaSkinningOptions& options, int num_bones)
    : options_(options),
      num_bones_(num_bones),
      encoding_(EncodingOptions(options)),
      mlp_(NetworkOptions(options, std::max(num_bones, 1))) {
  CHECK_GE(num_bones, 1) << "delta skinning needs bones";
}

void DeltaSkinning::InitializeParameters(uint32_t seed, double* params) const {
  mlp_.InitializeDefault(seed, params);
  const int last = mlp_.NumLinearLayers() - 1;
  std::fill(params + mlp_.WeightOffset(last), params + NumParameters(), 0.0);
}

bool DeltaSkinning::IsZero(const double* params) const {
  const int last = mlp_.NumLinearLayers() - 1;
  for (int k = mlp_.WeightOffset(last); k < NumParameters(); ++k) {
    if (params[k] != 0.0) return false;
  }
  return true;
}

void DeltaSkinning::ForwardBatch(const double* params, DeltaSkinningBatch* batch,
                                 bool jacobian) const {
  const int n = static_cast<int>(batch->x.cols());
  const int P = CodeDim();
  CHECK_EQ(batch->codes.rows(), P);
  CHECK_EQ(batch->codes.cols(), n);
  const int pe = encoding_.OutputDim();
  Eigen::MatrixXd encoded, d_encoded;
  encoding_.EncodeBatch(batch->x, &encoded, jacobian ? &d_encoded : nullptr);
  Eigen::MatrixXd input(pe + P, n);
  input.topRows(pe) = encoded;
  input.bottomRows(P) = batch->codes;
  mlp_.ForwardBatch(params, input, &batch->cache, &batch->logits);
  if (!jacobian) return;
  // Input tangents of sample j: d input / d x_c (c < 3), then unit vectors
  // of the code entries.
  const int k = LocalDim();
  Eigen::MatrixXd tangents = Eigen::MatrixXd::Zero(pe + P, static_cast<Eigen::Index>(k) * n);
  for (int j = 0; j < n; ++j) {
    tangents.block(0, static_cast<Eigen::Index>(k) * j, pe, 3) = d_encoded.middleCols<3>(3 * j);
    for (int c = 0; c < P; ++c) tangents(pe + c, static_cast<Eigen::Index>(k) * j + 3 + c) = 1.0;
  }
  mlp_.ForwardTangents(params, batch->cache, tangents, k, &batch->jacobian);
}

void DeltaSkinning::BackwardBatch(const double* params, const DeltaSkinningBatch& batch,
                                  const Eigen::MatrixXd& d_logits,
                                  const std::vector<int>& group_begin,
                                  Eigen::MatrixXd* d_params) const {
  mlp_.Backward(params, batch.cache, d_logits, group_begin, d_params, nullptr);
}

}  // namespace banmo
