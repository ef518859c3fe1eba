#include "banmo/field/mlp_widen.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace banmo {
namespace {

MlpOptions Options(Activation activation, int hidden_layers) {
  MlpOptions o;
  o.input_dim = 5;
  o.output_dim = 3;
  o.width = 8;
  o.hidden_layers = hidden_layers;
  o.activation = activation;
  o.softplus_beta = 10.0;  // smooth enough that every unit matters
  return o;
}

std::vector<double> RandomParams(const Mlp& mlp, uint32_t seed) {
  std::vector<double> p(mlp.NumParameters());
  mlp.InitializeDefault(seed, p.data());
  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int l = 0; l < mlp.NumLinearLayers(); ++l)
    for (int o = 0; o < mlp.LayerOutputDim(l); ++o) p[mlp.BiasOffset(l) + o] = u(rng);
  return p;
}

Eigen::MatrixXd RandomInputs(int rows, int cols, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Eigen::MatrixXd m(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) m(i, j) = u(rng);
  return m;
}

Eigen::MatrixXd Outputs(const Mlp& mlp, const std::vector<double>& p, const Eigen::MatrixXd& x) {
  MlpCache cache;
  Eigen::MatrixXd y;
  mlp.ForwardBatch(p.data(), x, &cache, &y);
  return y;
}

// The widened network computes the same function. Tolerance 1e-12: the
// outputs differ only by the rounding of the split sums (w/c summed c
// times); observed ~1e-16.
TEST(WidenMlp, PreservesTheFunctionAndHasTheNewWidth) {
  for (Activation act : {Activation::kSoftplus, Activation::kRelu}) {
    for (int layers : {1, 2, 3}) {
      for (int new_width : {8, 9, 16, 21}) {
        SCOPED_TRACE(::testing::Message() << "layers " << layers << " width " << new_width);
        const Mlp mlp(Options(act, layers));
        const std::vector<double> p = RandomParams(mlp, 11 + layers);
        std::mt19937 rng(5);
        const MlpWidening w = WidenMlp(mlp, p.data(), new_width, 0.0, &rng);
        EXPECT_EQ(w.options.width, new_width);
        const Mlp wide(w.options);
        ASSERT_EQ(static_cast<int>(w.params.size()), wide.NumParameters());
        for (int l = 0; l + 1 < wide.NumLinearLayers(); ++l) {
          EXPECT_EQ(wide.LayerOutputDim(l), new_width);
        }
        const Eigen::MatrixXd x = RandomInputs(5, 64, 3);
        const Eigen::MatrixXd y0 = Outputs(mlp, p, x);
        const Eigen::MatrixXd y1 = Outputs(wide, w.params, x);
        EXPECT_LT((y1 - y0).cwiseAbs().maxCoeff(), 1e-12);
        EXPECT_GT(y0.cwiseAbs().maxCoeff(), 0.1);  // not a trivial function
        // The old units keep their incoming weights.
        for (int i = 0; i < 5 * 8; ++i) EXPECT_EQ(w.params[i], p[i]) << i;
      }
    }
  }
}

// The gradient relation that carries Adam moments over:
// d/d new[k] = gradient_scale[k] * d/d old[source[k]] at the widening
// point (1e-12 relative: the same products, summed in another order).
TEST(WidenMlp, GradientScaleRelatesTheGradients) {
  const Mlp mlp(Options(Activation::kSoftplus, 2));
  const std::vector<double> p = RandomParams(mlp, 4);
  std::mt19937 rng(9);
  const MlpWidening w = WidenMlp(mlp, p.data(), 13, 0.0, &rng);
  const Mlp wide(w.options);
  const Eigen::MatrixXd x = RandomInputs(5, 32, 8);
  const Eigen::MatrixXd cot = RandomInputs(3, 32, 12);
  auto gradient = [&](const Mlp& m, const std::vector<double>& q) {
    MlpCache cache;
    Eigen::MatrixXd y, d_params;
    m.ForwardBatch(q.data(), x, &cache, &y);
    m.Backward(q.data(), cache, cot, {0, 32}, &d_params, nullptr);
    return Eigen::VectorXd(d_params.col(0));
  };
  const Eigen::VectorXd g0 = gradient(mlp, p);
  const Eigen::VectorXd g1 = gradient(wide, w.params);
  const double norm = g0.cwiseAbs().maxCoeff();
  ASSERT_GT(norm, 0.0);
  for (int k = 0; k < g1.size(); ++k) {
    ASSERT_GE(w.source[k], 0);
    EXPECT_NEAR(g1[k], w.gradient_scale[k] * g0[w.source[k]], 1e-12 * norm) << k;
  }
}

// Noise on the new units' incoming weights breaks the symmetry: the
// function moves a little, the old units do not, and the draw is
// deterministic in the generator's state.
TEST(WidenMlp, IncomingNoiseMovesOnlyTheNewUnitsAndIsDeterministic) {
  const Mlp mlp(Options(Activation::kSoftplus, 2));
  const std::vector<double> p = RandomParams(mlp, 6);
  std::mt19937 rng_a(21), rng_b(21);
  const MlpWidening a = WidenMlp(mlp, p.data(), 16, 0.01, &rng_a);
  const MlpWidening b = WidenMlp(mlp, p.data(), 16, 0.01, &rng_b);
  EXPECT_EQ(a.params, b.params);
  const Mlp wide(a.options);
  const Eigen::MatrixXd x = RandomInputs(5, 64, 3);
  const Eigen::MatrixXd y0 = Outputs(mlp, p, x);
  const double change = (Outputs(wide, a.params, x) - y0).cwiseAbs().maxCoeff();
  EXPECT_GT(change, 1e-9);
  EXPECT_LT(change, 0.05 * y0.cwiseAbs().maxCoeff());
  for (int i = 0; i < 5 * 8; ++i) EXPECT_EQ(a.params[i], p[i]) << i;
}

TEST(WidenMlp, LinearMapIsCopied) {
  const Mlp mlp(Options(Activation::kRelu, 0));
  const std::vector<double> p = RandomParams(mlp, 2);
  std::mt19937 rng(1);
  const MlpWidening w = WidenMlp(mlp, p.data(), 32, 0.0, &rng);
  EXPECT_EQ(w.params, p);
  EXPECT_EQ(w.options.width, mlp.options().width);
}

}  // namespace
}  // namespace banmo
