#include "banmo/field/encoding.h"

#include <gtest/gtest.h>

#include <random>

#include "banmo/util/dual.h"
#include "banmo/util/error.h"
#include "field_test_util.h"

namespace banmo {
namespace {

using test::JetJacobian;
using test::ScaledError;

Eigen::Matrix3Xd RandomPoints(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  Eigen::Matrix3Xd x(3, n);
  for (int j = 0; j < n; ++j)
    for (int c = 0; c < 3; ++c) x(c, j) = u(rng);
  return x;
}

TEST(PositionalEncoding, OutputDimAndLayout) {
  PositionalEncodingOptions o;
  o.num_bands = 2;
  const PositionalEncoding pe(o);
  EXPECT_EQ(pe.OutputDim(), 3 * (1 + 4));
  const double x[3] = {0.1, -0.2, 0.3};
  double out[15];
  pe.Encode(x, out);
  EXPECT_EQ(out[0], 0.1);
  EXPECT_EQ(out[2], 0.3);
  // Band 1 (2^1 pi): sin then cos of each coordinate.
  EXPECT_NEAR(out[3 + 6 + 1], std::sin(2.0 * M_PI * -0.2), 1e-15);
  EXPECT_NEAR(out[3 + 6 + 3 + 2], std::cos(2.0 * M_PI * 0.3), 1e-15);
  o.include_input = false;
  EXPECT_EQ(PositionalEncoding(o).OutputDim(), 12);
  o.num_bands = -1;
  EXPECT_THROW(o.Check(), InputError);
}

TEST(PositionalEncoding, BatchMatchesSinglePointAndJets) {
  PositionalEncodingOptions o;
  o.num_bands = 4;
  o.base_frequency = 0.7;
  PositionalEncoding pe(o);
  pe.SetAnnealing(2.4);  // partially annealed: weights 1, 1, 0.5(1-cos .4pi), 0
  const Eigen::Matrix3Xd x = RandomPoints(20, 1);
  Eigen::MatrixXd out, d, d2;
  pe.EncodeBatch(x, &out, &d);
  pe.EncodeSecondDerivativeBatch(x, &d2);
  const int D = pe.OutputDim();
  for (int j = 0; j < x.cols(); ++j) {
    Eigen::VectorXd ref(D);
    pe.Encode(x.col(j).data(), ref.data());
    EXPECT_LT((out.col(j) - ref).cwiseAbs().maxCoeff(), 1e-15);
    const Eigen::MatrixXd jac = JetJacobian<3>([&](const auto* xj, auto* o) { pe.Encode(xj, o); },
                                               Eigen::VectorXd(x.col(j)), D);
    EXPECT_LT(ScaledError(d.middleCols(3 * j, 3), jac), 1e-14);
    // Second derivatives: Jets over the tangent of a dual number.
    const Eigen::MatrixXd hess_diag = JetJacobian<3>(
        [&](const auto* xj, auto* o) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(xj)>>;
          Dual<J> xd[3];
          for (int c = 0; c < 3; ++c) xd[c] = Dual<J>(xj[c], J(1.0));
          std::vector<Dual<J>> od(D);
          pe.Encode(xd, od.data());
          for (int r = 0; r < D; ++r) o[r] = od[r].tangent;
        },
        Eigen::VectorXd(x.col(j)), D);
    for (int r = 0; r < D; ++r) {
      EXPECT_NEAR(d2(r, j), hess_diag(r, pe.InputCoordinate(r)), 1e-12 * (1 + std::abs(d2(r, j))));
    }
  }
}

TEST(PositionalEncoding, AnnealingWindow) {
  PositionalEncodingOptions o;
  o.num_bands = 3;
  PositionalEncoding pe(o);
  for (int l = 0; l < 3; ++l) EXPECT_EQ(pe.BandWeight(l), 1.0);
  pe.SetAnnealing(0.0);
  for (int l = 0; l < 3; ++l) EXPECT_EQ(pe.BandWeight(l), 0.0);
  pe.SetAnnealing(1.5);
  EXPECT_EQ(pe.BandWeight(0), 1.0);
  EXPECT_NEAR(pe.BandWeight(1), 0.5, 1e-15);
  EXPECT_EQ(pe.BandWeight(2), 0.0);
  pe.SetAnnealing(3.0);
  for (int l = 0; l < 3; ++l) EXPECT_EQ(pe.BandWeight(l), 1.0);
  const double x[3] = {0.3, 0.2, 0.1};
  double out[21];
  pe.SetAnnealing(0.0);
  pe.Encode(x, out);
  EXPECT_EQ(out[0], 0.3);
  for (int r = 3; r < 21; ++r) EXPECT_EQ(out[r], 0.0);
}

}  // namespace
}  // namespace banmo
