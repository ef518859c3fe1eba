#include "banmo/field/embedding_match_batch.h"

#include <gtest/gtest.h>

#include <random>

#include "field_test_util.h"

namespace banmo {
namespace {

using test::JetJacobian;
using test::ScaledError;

// Per-pixel embedding-weight gradients of X_hat against the full-Jet
// reference: SoftArgmax over the same K neighbours with psi from
// EvaluateEmbedding with Jets over all embedding weights. 1e-9 relative: both
// exact, only rounding order differs (as in mlp_test.cc).
TEST(EmbeddingMatchBatch, PerPixelWeightGradientsMatchFullJetReference) {
  CanonicalFieldOptions o;
  o.position_encoding.num_bands = 2;
  o.embedding_width = 8;
  o.embedding_layers = 1;
  const CanonicalField field(o);
  std::vector<double> sdf(field.SdfParameterSize()), color(field.ColorParameterSize()),
      emb(field.EmbeddingParameterSize());
  field.InitializeParameters(3, sdf.data(), color.data(), emb.data());
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double& v : emb) v += 0.3 * u(rng);

  // Canonical grid 8^3 and its psi.
  EmbeddingBatch grid_batch;
  grid_batch.x.resize(3, 512);
  for (int m = 0; m < 512; ++m) {
    grid_batch.x.col(m) =
        Eigen::Vector3d(m % 8, (m / 8) % 8, m / 64) * (2.0 / 7.0) - Eigen::Vector3d::Ones();
  }
  field.ForwardEmbeddingBatch(emb.data(), &grid_batch, false);
  EmbeddingMatcherOptions mo;
  mo.temperature = 10.0;
  EmbeddingMatcher matcher(mo);
  matcher.Build(grid_batch.x, grid_batch.psi);

  constexpr int kPixels = 5, kK = 8;
  EmbeddingMatchBatch batch;
  batch.features.resize(16, kPixels);
  for (int p = 0; p < kPixels; ++p) {
    double x[3] = {u(rng), u(rng), u(rng)};
    double psi[16];
    field.EvaluateEmbedding(emb.data(), x, psi);
    for (int d = 0; d < 16; ++d) batch.features(d, p) = psi[d] + 0.05 * u(rng);
  }
  MatchEmbeddingBatch(field, emb.data(), matcher, kK, &batch);
  Eigen::Matrix3Xd d_x_hat(3, kPixels);
  for (int p = 0; p < kPixels; ++p)
    for (int c = 0; c < 3; ++c) d_x_hat(c, p) = u(rng);
  Eigen::MatrixXd d_params, d_features;
  MatchEmbeddingBackward(field, emb.data(), matcher, batch, d_x_hat, &d_params, &d_features);
  ASSERT_EQ(d_params.cols(), kPixels);

  const Eigen::VectorXd pv = Eigen::Map<const Eigen::VectorXd>(emb.data(), emb.size());
  for (int p = 0; p < kPixels; ++p) {
    const std::vector<int>& idx = batch.matches[p].indices;
    ASSERT_EQ(static_cast<int>(idx.size()), kK);
    Eigen::Matrix3Xd points(3, kK);
    for (int i = 0; i < kK; ++i) points.col(i) = grid_batch.x.col(idx[i]);
    auto x_hat_of = [&](const auto* pj, const auto* f, auto* out) {
      using J = std::remove_const_t<std::remove_pointer_t<decltype(f)>>;
      std::vector<J> psi(16 * kK);
      for (int i = 0; i < kK; ++i) {
        J x[3];
        for (int c = 0; c < 3; ++c) x[c] = J(points(c, i));
        field.EvaluateEmbedding(pj, x, psi.data() + 16 * i);
      }
      SoftArgmax(f, psi.data(), points.data(), kK, mo.temperature, out);
    };
    const Eigen::MatrixXd jp = JetJacobian<32>(
        [&](const auto* pj, auto* out) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
          std::vector<J> f(16);
          for (int d = 0; d < 16; ++d) f[d] = J(batch.features(d, p));
          x_hat_of(pj, f.data(), out);
        },
        pv, 3);
    EXPECT_GT(d_params.col(p).norm(), 1e-3) << p;  // a non-trivial gradient
    EXPECT_LT(ScaledError(d_params.col(p), jp.transpose() * d_x_hat.col(p)), 1e-9) << p;
    const Eigen::MatrixXd jf = JetJacobian<16>(
        [&](const auto* f, auto* out) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(f)>>;
          std::vector<J> pj(emb.begin(), emb.end());
          x_hat_of(pj.data(), f, out);
        },
        Eigen::VectorXd(batch.features.col(p)), 3);
    EXPECT_LT(ScaledError(d_features.col(p), jf.transpose() * d_x_hat.col(p)), 1e-9) << p;
    // X_hat equals the reference value too.
    double ref[3];
    std::vector<double> psi(16 * kK);
    for (int i = 0; i < kK; ++i)
      for (int d = 0; d < 16; ++d) psi[16 * i + d] = grid_batch.psi(d, idx[i]);
    SoftArgmax(batch.features.col(p).data(), psi.data(), points.data(), kK, mo.temperature, ref);
    EXPECT_LT((Eigen::Vector3d(ref[0], ref[1], ref[2]) - batch.x_hat.col(p)).norm(), 1e-14);
  }
}

}  // namespace
}  // namespace banmo
