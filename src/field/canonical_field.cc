#include "banmo/field/canonical_field.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

const CanonicalFieldOptions& Checked(const CanonicalFieldOptions& options) {
  options.Check();
  return options;
}

int ColorInputDimOf(const CanonicalFieldOptions& o) {
  return o.geometry_feature_dim +
         (o.use_view_direction ? PositionalEncoding(o.view_encoding).OutputDim() : 0) +
         o.appearance_code_dim;
}

MlpOptions MakeMlpOptions(const CanonicalFieldOptions& o, int in, int out, int width, int layers) {
  MlpOptions m;
  m.input_dim = in;
  m.output_dim = out;
  m.width = width;
  m.hidden_layers = layers;
  m.activation = o.activation;
  m.softplus_beta = o.softplus_beta;
  return m;
}

// Portable standard normal draws (Box-Muller on raw std::mt19937 output).
class NormalSampler {
 public:
  explicit NormalSampler(uint32_t seed) : rng_(seed) {}
  double Next() {
    const double u1 = (static_cast<double>(rng_()) + 0.5) / 4294967296.0;
    const double u2 = (static_cast<double>(rng_()) + 0.5) / 4294967296.0;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }

 private:
  std::mt19937 rng_;
};

// d_x.col(j) = (d pe_j / d x_j)^T d_pe.col(j), dpe_dx: D x 3n.
void ChainEncodingTranspose(const Eigen::MatrixXd& dpe_dx, const Eigen::MatrixXd& d_pe,
                            Eigen::Matrix3Xd* d_x) {
  const int n = static_cast<int>(d_pe.cols());
  d_x->resize(3, n);
  ParallelFor(n, [&](int begin, int end) {
    for (int j = begin; j < end; ++j) {
      d_x->col(j).noalias() = dpe_dx.middleCols(3 * j, 3).transpose() * d_pe.col(j);
    }
  });
}

}  // namespace

void CanonicalFieldOptions::Check(const std::string& key) const {
  position_encoding.Check(key + ".position_encoding");
  if (!position_encoding.include_input) {
    ThrowInputError(key,
                    ".position_encoding.include_input must be true (geometric initialisation)");
  }
  if (use_view_direction) view_encoding.Check(key + ".view_encoding");
  // Upper limits bound the memory a model file or config can ask for
  // (docs/robustness.md): 4096 x 4096 weights per layer, 64 layers.
  constexpr int kMaxWidth = 4096, kMaxLayers = 64, kMaxDim = 1024;
  auto range = [&](const char* name, int v, int lo, int hi) {
    if (v < lo || v > hi)
      ThrowInputError(key, ".", name, " must be in [", lo, ", ", hi, "], got ", v);
  };
  range("sdf_width", sdf_width, 1, kMaxWidth);
  range("sdf_layers", sdf_layers, 1, kMaxLayers);
  range("geometry_feature_dim", geometry_feature_dim, 0, kMaxDim);
  range("color_width", color_width, 1, kMaxWidth);
  range("color_layers", color_layers, 0, kMaxLayers);
  range("appearance_code_dim", appearance_code_dim, 0, kMaxDim);
  range("embedding_width", embedding_width, 1, kMaxWidth);
  range("embedding_layers", embedding_layers, 0, kMaxLayers);
  if (!(softplus_beta > 0.0) || !std::isfinite(softplus_beta)) {
    ThrowInputError(key, ".softplus_beta must be finite and > 0");
  }
  if (!(init_sphere_radius > 0.0) || !std::isfinite(init_sphere_radius)) {
    ThrowInputError(key, ".init_sphere_radius must be finite and > 0");
  }
  if (ColorInputDimOf(*this) <= 0) {
    ThrowInputError(key,
                    ": the colour MLP has no input: set geometry_feature_dim > 0, "
                    "use_view_direction or appearance_code_dim > 0");
  }
}

CanonicalField::CanonicalField(const CanonicalFieldOptions& options)
    : options_(Checked(options)),
      pe_(options_.position_encoding),
      view_pe_(options_.view_encoding),
      sdf_mlp_(MakeMlpOptions(options_, pe_.OutputDim(), 1 + options_.geometry_feature_dim,
                              options_.sdf_width, options_.sdf_layers)),
      color_mlp_(MakeMlpOptions(options_, ColorInputDimOf(options_), 3, options_.color_width,
                                options_.color_layers)),
      embedding_mlp_(MakeMlpOptions(options_, pe_.OutputDim(), CanonicalFieldOptions::kEmbeddingDim,
                                    options_.embedding_width, options_.embedding_layers)) {}

int CanonicalField::ColorInputDim() const { return ColorInputDimOf(options_); }

void CanonicalField::InitializeParameters(uint32_t seed, double* sdf, double* color,
                                          double* embedding) const {
  // SAL geometric initialisation (Atzmon & Lipman 2020, Thm. 1), with the
  // Fourier features switched off in the first layer (NeuS/IDR practice):
  // hidden weights N(0, 2 / out), zero biases, last layer mean
  // sqrt(pi / in) with tiny spread and bias -r, so that for ReLU (softplus
  // with large beta) the expected output is |X| - r.
  NormalSampler normal(seed);
  const Mlp& m = sdf_mlp_;
  const int L = m.NumLinearLayers();
  for (int l = 0; l < L; ++l) {
    const int in = m.LayerInputDim(l), out = m.LayerOutputDim(l);
    double* w = sdf + m.WeightOffset(l);
    double* b = sdf + m.BiasOffset(l);
    for (int o = 0; o < out; ++o) {
      for (int i = 0; i < in; ++i) {
        double value;
        if (l + 1 == L) {
          value = (o == 0) ? std::sqrt(M_PI / in) + 1e-4 * normal.Next()
                           : normal.Next() / std::sqrt(static_cast<double>(in));
        } else if (l == 0 && i >= 3) {
          value = 0.0;  // Fourier features (the raw input is the first 3)
        } else {
          value = normal.Next() * std::sqrt(2.0 / out);
        }
        w[o * in + i] = value;
      }
      b[o] = (l + 1 == L && o == 0) ? -options_.init_sphere_radius : 0.0;
    }
  }
  // Calibration: the SAL expectation |X| - r holds only on average over
  // random networks; for a narrow network (tens of units) one draw is off by
  // ~0.3 on average. Refit the SDF output row (weights and bias) by ridge
  // least squares to |X| - r on kInitFitPoints points uniform in the ball of
  // radius kInitFitRadius (the hidden layers stay SAL's; deterministic).
  {
    constexpr int kInitFitPoints = 4096;
    constexpr double kInitFitRadius = 1.5;
    // Measured (width 64, 3 layers, 5 seeds): ridge 1e-6 -> largest weight
    // 6.5, mean error 0.015; 1e-3 -> 1.15, 0.017; 1e-2 -> 0.95, 0.025.
    constexpr double kInitRidge = 1e-3;
    std::mt19937 rng(seed ^ 0x5eedu);
    Eigen::Matrix3Xd x(3, kInitFitPoints);
    for (int j = 0; j < kInitFitPoints;) {
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) {
        p[c] = kInitFitRadius * (2.0 * ((static_cast<double>(rng()) + 0.5) / 4294967296.0) - 1.0);
      }
      if (p.norm() <= kInitFitRadius) x.col(j++) = p;
    }
    Eigen::MatrixXd pe;
    pe_.EncodeBatch(x, &pe, nullptr);
    MlpCache cache;
    m.ForwardBatch(sdf, pe, &cache, nullptr);
    const Eigen::MatrixXd& h = cache.a[L - 1];  // last hidden activations
    const int H = static_cast<int>(h.rows());
    Eigen::MatrixXd design(kInitFitPoints, H + 1);
    design.leftCols(H) = h.transpose();
    design.col(H).setOnes();
    Eigen::VectorXd target(kInitFitPoints);
    for (int j = 0; j < kInitFitPoints; ++j) {
      target[j] = x.col(j).norm() - options_.init_sphere_radius;
    }
    // Ridge toward the SAL draw (w0, -r): minimise
    // |design w - target|^2 + ridge |w - w0|^2, so near-collinear hidden
    // units do not get large opposite weights.
    Eigen::VectorXd w0(H + 1);
    for (int i = 0; i < H; ++i) w0[i] = sdf[m.WeightOffset(L - 1) + i];
    w0[H] = sdf[m.BiasOffset(L - 1)];
    Eigen::MatrixXd normal = design.transpose() * design;
    const double ridge = kInitRidge * normal.trace() / (H + 1);
    normal.diagonal().array() += ridge;
    const Eigen::VectorXd sol =
        w0 + normal.ldlt().solve(design.transpose() * (target - design * w0));
    double* w_last = sdf + m.WeightOffset(L - 1);
    for (int i = 0; i < H; ++i) w_last[i] = sol[i];  // row 0 of the last layer
    sdf[m.BiasOffset(L - 1)] = sol[H];
  }
  color_mlp_.InitializeDefault(seed + 1, color);
  embedding_mlp_.InitializeDefault(seed + 2, embedding);
}

void CanonicalField::ForwardBatch(const double* sdf_params, const double* color_params,
                                  FieldBatch* batch, bool input_jacobians) const {
  ForwardGeometryBatch(sdf_params, batch, input_jacobians);
  std::vector<int> all(static_cast<std::size_t>(batch->size()));
  std::iota(all.begin(), all.end(), 0);
  ForwardColorBatch(color_params, all, batch, input_jacobians);
}

namespace {

// The SDF MLP at every column of the batch (sdf, feature; with
// encoding_jacobian also dpe_dx), and no colour yet (BackwardBatch checks
// for it): the common start of ForwardGeometryBatch and ForwardSdfBatch.
void ForwardSdfMlp(const PositionalEncoding& pe, const Mlp& sdf_mlp, int feature_dim,
                   const double* sdf_params, bool encoding_jacobian, FieldBatch* batch) {
  CHECK(batch != nullptr);
  pe.EncodeBatch(batch->x, &batch->pe, encoding_jacobian ? &batch->dpe_dx : nullptr);
  if (!encoding_jacobian) batch->dpe_dx.resize(0, 0);
  Eigen::MatrixXd sdf_out;
  sdf_mlp.ForwardBatch(sdf_params, batch->pe, &batch->sdf_cache, &sdf_out);
  batch->sdf = sdf_out.row(0).transpose();
  batch->feature = sdf_out.bottomRows(feature_dim);
  batch->rgb.resize(3, 0);
  batch->color_columns.clear();
}

}  // namespace

void CanonicalField::ForwardGeometryBatch(const double* sdf_params, FieldBatch* batch,
                                          bool input_jacobians) const {
  ForwardSdfMlp(pe_, sdf_mlp_, options_.geometry_feature_dim, sdf_params, input_jacobians, batch);
  const int n = batch->size();
  if (!input_jacobians) {
    batch->dsdf_out_dx.resize(0, 0);
    return;
  }
  // SDF MLP outputs wrt x: forward tangents with the 3 encoding columns.
  sdf_mlp_.ForwardTangents(sdf_params, batch->sdf_cache, batch->dpe_dx, 3, &batch->dsdf_out_dx);
  batch->dsdf_dx.resize(3, n);
  for (int j = 0; j < n; ++j) {
    batch->dsdf_dx.col(j) = batch->dsdf_out_dx.block(0, 3 * j, 1, 3).transpose();
  }
}

void CanonicalField::ForwardColorBatch(const double* color_params, const std::vector<int>& columns,
                                       FieldBatch* batch, bool input_jacobians) const {
  CHECK(batch != nullptr);
  const int n = batch->size();
  const int m = static_cast<int>(columns.size());
  const int F = options_.geometry_feature_dim;
  const int A = options_.appearance_code_dim;
  const int V = options_.use_view_direction ? view_pe_.OutputDim() : 0;
  CHECK_EQ(batch->feature.cols(), n) << "call ForwardGeometryBatch first";
  if (input_jacobians) {
    CHECK_EQ(batch->dsdf_out_dx.cols(), 3 * n) << "call ForwardGeometryBatch with input_jacobians";
  }
  if (options_.use_view_direction) CHECK_EQ(batch->view_dir.cols(), n) << "view_dir size";
  if (A > 0) {
    CHECK_EQ(batch->appearance.rows(), A) << "appearance rows";
    CHECK_EQ(batch->appearance.cols(), n) << "appearance cols";
  }
  for (int k = 0; k < m; ++k) {
    CHECK(columns[k] >= 0 && columns[k] < n && (k == 0 || columns[k] > columns[k - 1]))
        << "colour columns must ascend within [0, " << n << ")";
  }
  batch->color_columns = columns;

  Eigen::MatrixXd& cin = batch->color_input;
  cin.resize(F + V + A, m);
  for (int k = 0; k < m; ++k) cin.col(k).head(F) = batch->feature.col(columns[k]);
  Eigen::MatrixXd dview_enc;  // V x 3m
  if (V > 0) {
    Eigen::Matrix3Xd view(3, m);
    for (int k = 0; k < m; ++k) view.col(k) = batch->view_dir.col(columns[k]);
    Eigen::MatrixXd view_enc;
    view_pe_.EncodeBatch(view, &view_enc, input_jacobians ? &dview_enc : nullptr);
    cin.middleRows(F, V) = view_enc;
  }
  if (A > 0) {
    for (int k = 0; k < m; ++k) cin.col(k).tail(A) = batch->appearance.col(columns[k]);
  }
  Eigen::MatrixXd logits;
  color_mlp_.ForwardBatch(color_params, cin, &batch->color_cache, &logits);
  // Overflow-free sigmoid.
  const Eigen::ArrayXXd e = (-logits.array().abs()).exp();
  const Eigen::MatrixXd rgb =
      (logits.array() > 0.0).select(1.0 / (1.0 + e), e / (1.0 + e)).matrix();
  batch->rgb.setZero(3, n);
  for (int k = 0; k < m; ++k) batch->rgb.col(columns[k]) = rgb.col(k);
  if (!input_jacobians) return;

  // Colour MLP: one reverse pass per output channel gives d rgb_c / d input.
  const Eigen::ArrayXXd ds = rgb.array() * (1.0 - rgb.array());  // sigmoid'
  std::vector<Eigen::MatrixXd> dcin(3);
  for (int c = 0; c < 3; ++c) {
    Eigen::MatrixXd d_logits = Eigen::MatrixXd::Zero(3, m);
    d_logits.row(c) = ds.row(c).matrix();
    color_mlp_.Backward(color_params, batch->color_cache, d_logits, {0}, nullptr, &dcin[c]);
  }
  batch->drgb_dx.setZero(3, 3 * n);
  batch->drgb_dview.setZero(3, 3 * n);
  batch->drgb_dappearance.setZero(3, static_cast<Eigen::Index>(A) * n);
  const Eigen::MatrixXd& t = batch->dsdf_out_dx;
  ParallelFor(m, [&](int begin, int end) {
    Eigen::MatrixXd jac(3, F + V + A);
    for (int k = begin; k < end; ++k) {
      const int j = columns[k];
      for (int c = 0; c < 3; ++c) jac.row(c) = dcin[c].col(k).transpose();
      batch->drgb_dx.middleCols(3 * j, 3).noalias() = jac.leftCols(F) * t.block(1, 3 * j, F, 3);
      if (V > 0) {
        batch->drgb_dview.middleCols(3 * j, 3).noalias() =
            jac.middleCols(F, V) * dview_enc.middleCols(3 * k, 3);
      }
      if (A > 0) {
        batch->drgb_dappearance.middleCols(static_cast<Eigen::Index>(A) * j, A) = jac.rightCols(A);
      }
    }
  });
}

void CanonicalField::ForwardSdfBatch(const double* sdf_params, FieldBatch* batch,
                                     bool sdf_gradient) const {
  ForwardSdfMlp(pe_, sdf_mlp_, options_.geometry_feature_dim, sdf_params, sdf_gradient, batch);
  const int n = batch->size();
  batch->color_input.resize(0, 0);
  batch->color_cache = MlpCache();
  if (!sdf_gradient) return;
  Eigen::MatrixXd d_out = Eigen::MatrixXd::Zero(sdf_mlp_.OutputDim(), n);
  d_out.row(0).setOnes();
  Eigen::MatrixXd d_pe;
  sdf_mlp_.Backward(sdf_params, batch->sdf_cache, d_out, {0}, nullptr, &d_pe);
  ChainEncodingTranspose(batch->dpe_dx, d_pe, &batch->dsdf_dx);
}

void CanonicalField::BackwardBatch(const double* sdf_params, const double* color_params,
                                   const FieldBatch& batch, const Eigen::VectorXd& d_sdf,
                                   const Eigen::Matrix3Xd& d_rgb,
                                   const std::vector<int>& group_begin,
                                   Eigen::MatrixXd* d_sdf_params, Eigen::MatrixXd* d_color_params,
                                   Eigen::Matrix3Xd* d_x) const {
  const int n = batch.size();
  const int F = options_.geometry_feature_dim;
  CHECK_EQ(d_sdf.size(), n);
  CHECK_EQ(d_rgb.cols(), n);
  CHECK_EQ(batch.rgb.cols(), n) << "call ForwardBatch (or ForwardColorBatch) first";
  const std::vector<int>& cols = batch.color_columns;
  const int m = static_cast<int>(cols.size());
  CHECK_EQ(batch.color_cache.num_samples(), m);
  // The colour MLP ran on cols only (all n, in order, when m = n).
  const bool all = m == n;
  Eigen::MatrixXd d_logits(3, m);
  for (int k = 0; k < m; ++k) {
    const int j = cols[k];
    d_logits.col(k) =
        (d_rgb.col(j).array() * batch.rgb.col(j).array() * (1.0 - batch.rgb.col(j).array()))
            .matrix();
  }
  std::vector<int> color_groups = group_begin;
  if (!all) {
    for (int& g : color_groups) {
      g = static_cast<int>(std::lower_bound(cols.begin(), cols.end(), g) - cols.begin());
    }
  }
  const bool need_sdf = d_sdf_params != nullptr || d_x != nullptr;
  Eigen::MatrixXd d_cin;
  color_mlp_.Backward(color_params, batch.color_cache, d_logits, color_groups, d_color_params,
                      need_sdf ? &d_cin : nullptr);
  if (!need_sdf) return;
  Eigen::MatrixXd d_out(1 + F, n);
  d_out.row(0) = d_sdf.transpose();
  if (all) {
    d_out.bottomRows(F) = d_cin.topRows(F);
  } else {
    d_out.bottomRows(F).setZero();
    for (int k = 0; k < m; ++k) d_out.col(cols[k]).tail(F) = d_cin.col(k).head(F);
  }
  Eigen::MatrixXd d_pe;
  sdf_mlp_.Backward(sdf_params, batch.sdf_cache, d_out, group_begin, d_sdf_params,
                    d_x != nullptr ? &d_pe : nullptr);
  if (d_x == nullptr) return;
  if (batch.dpe_dx.cols() == 3 * n) {
    ChainEncodingTranspose(batch.dpe_dx, d_pe, d_x);
  } else {
    Eigen::MatrixXd pe, dpe_dx;
    pe_.EncodeBatch(batch.x, &pe, &dpe_dx);
    ChainEncodingTranspose(dpe_dx, d_pe, d_x);
  }
}

void CanonicalField::SdfGradientBackward(const double* sdf_params, const FieldBatch& batch,
                                         const Eigen::Matrix3Xd& c,
                                         const std::vector<int>& group_begin,
                                         Eigen::MatrixXd* d_sdf_params,
                                         Eigen::Matrix3Xd* d_x) const {
  const int n = batch.size();
  CHECK_EQ(c.cols(), n);
  CHECK_EQ(batch.sdf_cache.num_samples(), n) << "call ForwardBatch first";
  Eigen::MatrixXd pe, dpe_dx_local;
  const Eigen::MatrixXd* dpe_dx = &batch.dpe_dx;
  if (batch.dpe_dx.cols() != 3 * n) {
    pe_.EncodeBatch(batch.x, &pe, &dpe_dx_local);
    dpe_dx = &dpe_dx_local;
  }
  const int D = pe_.OutputDim();
  // S = sum_j c_j . grad sdf(x_j) = sum_j e_0^T J_mlp(pe_j) (dpe/dx_j c_j):
  // tangent v_j = dpe/dx_j c_j, tangent cotangent e_0.
  Eigen::MatrixXd v(D, n);
  ParallelFor(n, [&](int begin, int end) {
    for (int j = begin; j < end; ++j) v.col(j).noalias() = dpe_dx->middleCols(3 * j, 3) * c.col(j);
  });
  Eigen::MatrixXd cot = Eigen::MatrixXd::Zero(sdf_mlp_.OutputDim(), n);
  cot.row(0).setOnes();
  Eigen::MatrixXd a_bar, a_dot_bar;
  sdf_mlp_.BackwardOfTangent(sdf_params, batch.sdf_cache, v, cot, group_begin, d_sdf_params,
                             d_x != nullptr ? &a_bar : nullptr,
                             d_x != nullptr ? &a_dot_bar : nullptr);
  if (d_x == nullptr) return;
  // dS/dx_j = dpe/dx_j^T a_bar_j + sum_r a_dot_bar_rj d2pe_rj c_{coord(r) j}.
  ChainEncodingTranspose(*dpe_dx, a_bar, d_x);
  Eigen::MatrixXd d2;
  pe_.EncodeSecondDerivativeBatch(batch.x, &d2);
  for (int j = 0; j < n; ++j) {
    for (int r = 0; r < D; ++r) {
      const int i = pe_.InputCoordinate(r);
      (*d_x)(i, j) += a_dot_bar(r, j) * d2(r, j) * c(i, j);
    }
  }
}

void CanonicalField::ForwardEmbeddingBatch(const double* params, EmbeddingBatch* batch,
                                           bool input_jacobians) const {
  CHECK(batch != nullptr);
  const int n = batch->size();
  // The encoding's Jacobian (D x 3n) only where it is read: the match
  // grid's and the embedding-only samples' batches do without.
  pe_.EncodeBatch(batch->x, &batch->pe, input_jacobians ? &batch->dpe_dx : nullptr);
  embedding_mlp_.ForwardBatch(params, batch->pe, &batch->cache, &batch->psi);
  if (!input_jacobians) {
    batch->dpe_dx.resize(0, 0);
    return;
  }
  Eigen::MatrixXd t;
  embedding_mlp_.ForwardTangents(params, batch->cache, batch->dpe_dx, 3, &t);
  batch->dpsi_dx = std::move(t);
  CHECK_EQ(batch->dpsi_dx.cols(), 3 * n);
}

void CanonicalField::BackwardEmbeddingBatch(const double* params, const EmbeddingBatch& batch,
                                            const Eigen::MatrixXd& d_psi,
                                            const std::vector<int>& group_begin,
                                            Eigen::MatrixXd* d_params,
                                            Eigen::Matrix3Xd* d_x) const {
  const int n = batch.size();
  CHECK_EQ(d_psi.rows(), EmbeddingDim());
  CHECK_EQ(d_psi.cols(), n);
  CHECK_EQ(batch.cache.num_samples(), n) << "call ForwardEmbeddingBatch first";
  Eigen::MatrixXd d_pe;
  embedding_mlp_.Backward(params, batch.cache, d_psi, group_begin, d_params,
                          d_x != nullptr ? &d_pe : nullptr);
  if (d_x != nullptr) {
    CHECK_EQ(batch.dpe_dx.cols(), 3 * n) << "d_x needs ForwardEmbeddingBatch with input_jacobians";
    ChainEncodingTranspose(batch.dpe_dx, d_pe, d_x);
  }
}

}  // namespace banmo
