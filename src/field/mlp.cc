#include "banmo/field/mlp.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstWeightMap = Eigen::Map<const RowMajorMatrix>;
using WeightMap = Eigen::Map<RowMajorMatrix>;

void CheckGroups(const std::vector<int>& group_begin, int n) {
  CHECK_GE(group_begin.size(), 1u) << "group_begin needs G+1 entries";
  CHECK_GE(group_begin.front(), 0);
  for (size_t g = 1; g < group_begin.size(); ++g) {
    CHECK_LE(group_begin[g - 1], group_begin[g]) << "group_begin must be non-decreasing";
  }
  CHECK_LE(group_begin.back(), n) << "group_begin.back() exceeds the number of samples";
}

}  // namespace

void MlpOptions::Check(const std::string& key) const {
  if (input_dim <= 0) ThrowInputError(key, ".input_dim must be > 0, got ", input_dim);
  if (output_dim <= 0) ThrowInputError(key, ".output_dim must be > 0, got ", output_dim);
  if (width <= 0) ThrowInputError(key, ".width must be > 0, got ", width);
  if (hidden_layers < 0) ThrowInputError(key, ".hidden_layers must be >= 0, got ", hidden_layers);
  if (!(softplus_beta > 0.0) || !std::isfinite(softplus_beta)) {
    ThrowInputError(key, ".softplus_beta must be finite and > 0");
  }
}

Mlp::Mlp(const MlpOptions& options) : options_(options) {
  options_.Check();
  dims_.push_back(options_.input_dim);
  for (int h = 0; h < options_.hidden_layers; ++h) dims_.push_back(options_.width);
  dims_.push_back(options_.output_dim);
  int offset = 0;
  for (int l = 0; l + 1 < static_cast<int>(dims_.size()); ++l) {
    weight_offset_.push_back(offset);
    offset += dims_[l] * dims_[l + 1];
    bias_offset_.push_back(offset);
    offset += dims_[l + 1];
  }
  num_parameters_ = offset;
  max_dim_ = *std::max_element(dims_.begin(), dims_.end());
}

void Mlp::InitializeDefault(uint32_t seed, double* params) const {
  std::mt19937 rng(seed);
  for (int l = 0; l < NumLinearLayers(); ++l) {
    const int in = dims_[l], out = dims_[l + 1];
    const double limit = std::sqrt(6.0 / (in + out));
    // Uniform from the raw 32-bit draws (std::mt19937 output is specified by
    // the standard; the distributions are not), so the result is portable.
    for (int i = 0; i < in * out; ++i) {
      const double u = (static_cast<double>(rng()) + 0.5) / 4294967296.0;  // (0, 1)
      params[weight_offset_[l] + i] = limit * (2.0 * u - 1.0);
    }
    for (int o = 0; o < out; ++o) params[bias_offset_[l] + o] = 0.0;
  }
}

// Heaviside step H(x) = 1 for x > 0, else 0, vectorisable: max(x, 0) / |x|
// is exactly 1 for x > 0 (x / x) and 0 otherwise.
template <typename Derived>
static auto Step(const Eigen::ArrayBase<Derived>& x) {
  return x.max(0.0) / x.abs().max(std::numeric_limits<double>::min());
}

// Applies the activation to a block of pre-activations; writes the
// activations and their derivatives.
static void ActivateBlock(const MlpOptions& options, const Eigen::Ref<const Eigen::MatrixXd>& z,
                          Eigen::Ref<Eigen::MatrixXd> a, Eigen::Ref<Eigen::MatrixXd> da) {
  if (options.activation == Activation::kSoftplus) {
    const double beta = options.softplus_beta;
    const Eigen::ArrayXXd bz = beta * z.array();
    const Eigen::ArrayXXd e = (-bz.abs()).exp();  // in (0, 1]: no overflow
    // log1p(e) via the vectorisable log with the classic correction
    // log1p(e) = log(u) - ((u - 1) - e) / u, u = 1 + e (exact to rounding,
    // also for e below machine epsilon where it returns e); Eigen's double
    // log1p is scalar and was the bottleneck of the forward pass.
    const Eigen::ArrayXXd u = 1.0 + e;
    a.array() = z.array().max(0.0) + (u.log() - ((u - 1.0) - e) / u) / beta;
    // sigmoid(bz) = (bz > 0 ? 1 : e) / (1 + e), written with max and the
    // 0/1 step H so that Eigen vectorises it (select() compiled to scalar
    // branches here).
    da.array() = e.max(Step(bz)) / u;
  } else {
    a.array() = z.array().max(0.0);
    da.array() = Step(z.array());
  }
}

void Mlp::ForwardBatch(const double* params, const Eigen::MatrixXd& inputs, MlpCache* cache,
                       Eigen::MatrixXd* outputs) const {
  CHECK(cache != nullptr);
  CHECK_EQ(inputs.rows(), InputDim());
  const int n = static_cast<int>(inputs.cols());
  const int L = NumLinearLayers();
  cache->a.resize(L);
  cache->z.resize(L);
  cache->dact.resize(L - 1);
  cache->a[0] = inputs;
  for (int l = 0; l < L; ++l) {
    cache->z[l].resize(dims_[l + 1], n);
    if (l + 1 < L) {
      cache->a[l + 1].resize(dims_[l + 1], n);
      cache->dact[l].resize(dims_[l + 1], n);
    }
  }
  // Tiles of kTile samples run through all layers while their activations
  // are in cache; the activation temporaries stay tile-sized.
  constexpr int kTile = 256;
  ParallelFor(n, [&](int begin, int end) {
    for (int t0 = begin; t0 < end; t0 += kTile) {
      const int m = std::min(kTile, end - t0);
      for (int l = 0; l < L; ++l) {
        const ConstWeightMap w(params + weight_offset_[l], dims_[l + 1], dims_[l]);
        const Eigen::Map<const Eigen::VectorXd> b(params + bias_offset_[l], dims_[l + 1]);
        auto z = cache->z[l].middleCols(t0, m);
        z.noalias() = w * cache->a[l].middleCols(t0, m);
        z.colwise() += b;
        if (l + 1 < L) {
          ActivateBlock(options_, z, cache->a[l + 1].middleCols(t0, m),
                        cache->dact[l].middleCols(t0, m));
        }
      }
    }
  });
  if (outputs != nullptr) *outputs = cache->z.back();
}

void Mlp::ForwardTangents(const double* params, const MlpCache& cache,
                          const Eigen::MatrixXd& input_tangents, int k,
                          Eigen::MatrixXd* output_tangents) const {
  CHECK(output_tangents != nullptr);
  CHECK_GT(k, 0);
  const int n = cache.num_samples();
  CHECK_EQ(input_tangents.rows(), InputDim());
  CHECK_EQ(input_tangents.cols(), static_cast<Eigen::Index>(k) * n);
  const int L = NumLinearLayers();
  output_tangents->resize(OutputDim(), static_cast<Eigen::Index>(k) * n);
  ParallelFor(n, [&](int begin, int end) {
    const int m = end - begin;
    Eigen::MatrixXd t = input_tangents.middleCols(static_cast<Eigen::Index>(k) * begin, k * m);
    Eigen::MatrixXd u;
    for (int l = 0; l < L; ++l) {
      const ConstWeightMap w(params + weight_offset_[l], dims_[l + 1], dims_[l]);
      u.noalias() = w * t;
      if (l + 1 < L) {
        const Eigen::MatrixXd& da = cache.dact[l];
        for (int j = 0; j < m; ++j) {
          u.middleCols(static_cast<Eigen::Index>(k) * j, k).array().colwise() *=
              da.col(begin + j).array();
        }
      }
      t.swap(u);
    }
    output_tangents->middleCols(static_cast<Eigen::Index>(k) * begin, k * m) = t;
  });
}

namespace {

// One term of a per-group weight gradient: dW_l += delta_l * input_l^T over
// the group's samples (delta: out_l x n, input: in_l x n).
struct GradientTerm {
  const Eigen::MatrixXd* delta;
  const Eigen::MatrixXd* input;
};

}  // namespace

// d_params(:, g) = sum over terms of layer l: delta[:, g] input[:, g]^T (into
// W_l) and sum over the group of bias_delta (into b_l).
// Writes the gradient of samples [b, b + m) into column (NumParameters
// doubles): per layer, dW = sum over terms of delta * input^T, db = sum of
// bias_delta.
static void GroupGradient(const Mlp& mlp, const std::vector<std::vector<GradientTerm>>& terms,
                          const std::vector<const Eigen::MatrixXd*>& bias_delta, int b, int m,
                          double* column) {
  for (int l = 0; l < mlp.NumLinearLayers(); ++l) {
    const int in = mlp.LayerInputDim(l), out = mlp.LayerOutputDim(l);
    WeightMap dw(column + mlp.WeightOffset(l), out, in);
    Eigen::Map<Eigen::VectorXd> db(column + mlp.BiasOffset(l), out);
    if (m == 0) {
      dw.setZero();
      db.setZero();
      continue;
    }
    bool first = true;
    for (const GradientTerm& term : terms[l]) {
      if (first) {
        dw.noalias() = term.delta->middleCols(b, m) * term.input->middleCols(b, m).transpose();
        first = false;
      } else {
        dw.noalias() += term.delta->middleCols(b, m) * term.input->middleCols(b, m).transpose();
      }
    }
    if (bias_delta[l] != nullptr) {
      db = bias_delta[l]->middleCols(b, m).rowwise().sum();
    } else {
      db.setZero();
    }
  }
}

// d_params(:, g) = gradient of group g (see GroupGradient). Parallel over
// groups; when there are fewer groups than threads (e.g. one group = the
// whole batch, the J^T r gradient), each group is split into per-thread
// partial sums added in a fixed order (deterministic for a fixed thread
// count).
static void PerGroupGradients(const Mlp& mlp, const std::vector<std::vector<GradientTerm>>& terms,
                              const std::vector<const Eigen::MatrixXd*>& bias_delta,
                              const std::vector<int>& group_begin, Eigen::MatrixXd* d_params) {
  const int G = static_cast<int>(group_begin.size()) - 1;
  const int P = mlp.NumParameters();
  d_params->resize(P, G);
  const int threads = NumThreads();
  if (G >= threads) {
    ParallelFor(G, [&](int g_begin, int g_end) {
      for (int g = g_begin; g < g_end; ++g) {
        GroupGradient(mlp, terms, bias_delta, group_begin[g], group_begin[g + 1] - group_begin[g],
                      d_params->col(g).data());
      }
    });
    return;
  }
  for (int g = 0; g < G; ++g) {
    const int b = group_begin[g];
    const int m = group_begin[g + 1] - b;
    const int chunk = std::max(1, (m + threads - 1) / threads);
    const int num_chunks = std::max(1, (m + chunk - 1) / chunk);
    Eigen::MatrixXd partial(P, num_chunks);
    ParallelFor(num_chunks, [&](int c_begin, int c_end) {
      for (int c = c_begin; c < c_end; ++c) {
        const int cb = std::min(m, c * chunk);
        GroupGradient(mlp, terms, bias_delta, b + cb, std::min(m, cb + chunk) - cb,
                      partial.col(c).data());
      }
    });
    d_params->col(g) = partial.rowwise().sum();
  }
}

void Mlp::Backward(const double* params, const MlpCache& cache, const Eigen::MatrixXd& d_outputs,
                   const std::vector<int>& group_begin, Eigen::MatrixXd* d_params,
                   Eigen::MatrixXd* d_inputs) const {
  const int n = cache.num_samples();
  CHECK_EQ(d_outputs.rows(), OutputDim());
  CHECK_EQ(d_outputs.cols(), n);
  if (d_params != nullptr) CheckGroups(group_begin, n);
  const int L = NumLinearLayers();
  // delta[l] = d(loss)/d z_l for every layer.
  std::vector<Eigen::MatrixXd> delta(L);
  for (int l = 0; l + 1 < L; ++l) delta[l].resize(dims_[l + 1], n);
  if (d_inputs != nullptr) d_inputs->resize(InputDim(), n);
  ParallelFor(n, [&](int begin, int end) {
    const int m = end - begin;
    Eigen::MatrixXd back;
    for (int l = L - 1; l >= 0; --l) {
      if (l == 0 && d_inputs == nullptr) break;
      const ConstWeightMap w(params + weight_offset_[l], dims_[l + 1], dims_[l]);
      const Eigen::MatrixXd& dl = (l == L - 1) ? d_outputs : delta[l];
      back.noalias() = w.transpose() * dl.middleCols(begin, m);
      if (l == 0) {
        d_inputs->middleCols(begin, m) = back;
      } else {
        delta[l - 1].middleCols(begin, m) =
            back.cwiseProduct(cache.dact[l - 1].middleCols(begin, m));
      }
    }
  });
  if (d_params == nullptr) return;
  std::vector<std::vector<GradientTerm>> terms(L);
  std::vector<const Eigen::MatrixXd*> bias_delta(L);
  for (int l = 0; l < L; ++l) {
    const Eigen::MatrixXd* dl = (l == L - 1) ? &d_outputs : &delta[l];
    terms[l].push_back({dl, &cache.a[l]});
    bias_delta[l] = dl;
  }
  PerGroupGradients(*this, terms, bias_delta, group_begin, d_params);
}

void Mlp::BackwardOfTangent(const double* params, const MlpCache& cache,
                            const Eigen::MatrixXd& input_tangents,
                            const Eigen::MatrixXd& tangent_cotangents,
                            const std::vector<int>& group_begin, Eigen::MatrixXd* d_params,
                            Eigen::MatrixXd* d_inputs, Eigen::MatrixXd* d_input_tangents) const {
  const int n = cache.num_samples();
  CHECK_EQ(input_tangents.rows(), InputDim());
  CHECK_EQ(input_tangents.cols(), n);
  CHECK_EQ(tangent_cotangents.rows(), OutputDim());
  CHECK_EQ(tangent_cotangents.cols(), n);
  if (d_params != nullptr) CheckGroups(group_begin, n);
  const int L = NumLinearLayers();
  const bool softplus = options_.activation == Activation::kSoftplus;
  const double beta = options_.softplus_beta;
  // Primal of the tangent map: a_dot[l] = tangent of layer l's input
  // (a_dot[0] = v), z_dot[l] = tangent of z_l. Adjoints: z_dot_bar[l] and
  // z_bar[l] (the latter is zero at the output layer: S does not depend on
  // the output value itself).
  std::vector<Eigen::MatrixXd> a_dot(L), z_dot(L), z_dot_bar(L), z_bar(L);
  for (int l = 0; l < L; ++l) {
    if (l > 0) a_dot[l].resize(dims_[l], n);
    z_dot[l].resize(dims_[l + 1], n);
    if (l + 1 < L) {
      z_dot_bar[l].resize(dims_[l + 1], n);
      z_bar[l].resize(dims_[l + 1], n);
    }
  }
  if (d_inputs != nullptr) d_inputs->resize(InputDim(), n);
  if (d_input_tangents != nullptr) d_input_tangents->resize(InputDim(), n);
  ParallelFor(n, [&](int begin, int end) {
    const int m = end - begin;
    // Forward tangents.
    for (int l = 0; l < L; ++l) {
      const ConstWeightMap w(params + weight_offset_[l], dims_[l + 1], dims_[l]);
      const Eigen::MatrixXd& in = (l == 0) ? input_tangents : a_dot[l];
      z_dot[l].middleCols(begin, m).noalias() = w * in.middleCols(begin, m);
      if (l + 1 < L) {
        a_dot[l + 1].middleCols(begin, m) =
            z_dot[l].middleCols(begin, m).cwiseProduct(cache.dact[l].middleCols(begin, m));
      }
    }
    // Reverse.
    Eigen::MatrixXd a_dot_bar, a_bar;
    for (int l = L - 1; l >= 0; --l) {
      const ConstWeightMap w(params + weight_offset_[l], dims_[l + 1], dims_[l]);
      const bool output_layer = (l == L - 1);
      const Eigen::MatrixXd& zdb = output_layer ? tangent_cotangents : z_dot_bar[l];
      if (l == 0 && d_inputs == nullptr && d_input_tangents == nullptr) break;
      a_dot_bar.noalias() = w.transpose() * zdb.middleCols(begin, m);
      if (output_layer) {
        a_bar.setZero(dims_[l], m);
      } else {
        a_bar.noalias() = w.transpose() * z_bar[l].middleCols(begin, m);
      }
      if (l == 0) {
        if (d_inputs != nullptr) d_inputs->middleCols(begin, m) = a_bar;
        if (d_input_tangents != nullptr) d_input_tangents->middleCols(begin, m) = a_dot_bar;
        break;
      }
      // Layer l's input is a_l = act(z_{l-1}), a_dot_l = act'(z_{l-1}) z_dot_{l-1}.
      const auto da = cache.dact[l - 1].middleCols(begin, m);
      z_dot_bar[l - 1].middleCols(begin, m) = a_dot_bar.cwiseProduct(da);
      auto zb = z_bar[l - 1].middleCols(begin, m);
      zb = a_bar.cwiseProduct(da);
      if (softplus) {
        // act'' = beta * s (1 - s) with s = act'.
        zb.array() += beta * da.array() * (1.0 - da.array()) *
                      z_dot[l - 1].middleCols(begin, m).array() * a_dot_bar.array();
      }
    }
  });
  if (d_params == nullptr) return;
  std::vector<std::vector<GradientTerm>> terms(L);
  std::vector<const Eigen::MatrixXd*> bias_delta(L, nullptr);
  for (int l = 0; l < L; ++l) {
    const Eigen::MatrixXd* zdb = (l == L - 1) ? &tangent_cotangents : &z_dot_bar[l];
    const Eigen::MatrixXd* in_dot = (l == 0) ? &input_tangents : &a_dot[l];
    terms[l].push_back({zdb, in_dot});
    if (l + 1 < L) {
      terms[l].push_back({&z_bar[l], &cache.a[l]});
      bias_delta[l] = &z_bar[l];
    }
  }
  PerGroupGradients(*this, terms, bias_delta, group_begin, d_params);
}

}  // namespace banmo
