#include "banmo/field/mlp.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "../common/thread_count_guard.h"
#include "banmo/util/dual.h"
#include "banmo/util/parallel.h"
#include "field_test_util.h"

namespace banmo {
namespace {

using test::JetJacobian;
using test::ScaledError;

// Tolerances. The batched and templated paths compute the same exact
// derivatives (no approximation), and differ only in floating-point
// summation order (GEMM blocking, per-group sums of ~10-40 samples of O(1)
// terms): observed differences are ~1e-15 relative, so 1e-9 (the docs/design.md
// target for residual Jacobians) catches any real error (a wrong term is
// O(1e-3) or more) with ample margin. Values: 1e-12.
constexpr double kValueTol = 1e-12;
constexpr double kGradTol = 1e-9;

MlpOptions SmallOptions(Activation act, double beta = 100.0) {
  MlpOptions o;
  o.input_dim = 5;
  o.output_dim = 3;
  o.width = 8;
  o.hidden_layers = 2;
  o.activation = act;
  o.softplus_beta = beta;
  return o;
}

Eigen::MatrixXd RandomMatrix(int rows, int cols, uint32_t seed, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::MatrixXd m(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) m(i, j) = u(rng);
  return m;
}

std::vector<double> Params(const Mlp& mlp, uint32_t seed) {
  std::vector<double> p(mlp.NumParameters());
  mlp.InitializeDefault(seed, p.data());
  // Non-zero biases, so the bias gradients are exercised at a generic point.
  std::mt19937 rng(seed + 100);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  for (int l = 0; l < mlp.NumLinearLayers(); ++l)
    for (int o = 0; o < mlp.LayerOutputDim(l); ++o) p[mlp.BiasOffset(l) + o] = u(rng);
  return p;
}

const std::vector<int> kGroups = {0, 5, 5, 17, 30, 37};  // includes an empty group
constexpr int kN = 40;                                   // samples 37..39 are in no group

class MlpTest : public ::testing::TestWithParam<std::pair<Activation, double>> {};

TEST_P(MlpTest, LayoutAndSize) {
  const Mlp mlp(SmallOptions(GetParam().first, GetParam().second));
  EXPECT_EQ(mlp.NumParameters(), 5 * 8 + 8 + 8 * 8 + 8 + 8 * 3 + 3);
  EXPECT_EQ(mlp.WeightOffset(1), 48);
  EXPECT_EQ(mlp.BiasOffset(2), 48 + 72 + 24);
}

TEST_P(MlpTest, ForwardBatchEqualsForward) {
  const Mlp mlp(SmallOptions(GetParam().first, GetParam().second));
  const auto p = Params(mlp, 3);
  const Eigen::MatrixXd x = RandomMatrix(5, kN, 7);
  MlpCache cache;
  Eigen::MatrixXd y;
  mlp.ForwardBatch(p.data(), x, &cache, &y);
  ASSERT_EQ(y.rows(), 3);
  ASSERT_EQ(y.cols(), kN);
  for (int j = 0; j < kN; ++j) {
    Eigen::Vector3d ref;
    mlp.Forward(p.data(), x.col(j).data(), ref.data());
    EXPECT_LT((y.col(j) - ref).norm(), kValueTol * std::max(1.0, ref.norm())) << j;
  }
}

TEST_P(MlpTest, ForwardTangentsMatchJets) {
  const Mlp mlp(SmallOptions(GetParam().first, GetParam().second));
  const auto p = Params(mlp, 4);
  const Eigen::MatrixXd x = RandomMatrix(5, kN, 8);
  constexpr int k = 2;
  const Eigen::MatrixXd v = RandomMatrix(5, k * kN, 9);
  MlpCache cache;
  mlp.ForwardBatch(p.data(), x, &cache, nullptr);
  Eigen::MatrixXd t;
  mlp.ForwardTangents(p.data(), cache, v, k, &t);
  for (int j = 0; j < kN; ++j) {
    const Eigen::MatrixXd jac =
        JetJacobian<5>([&](const auto* xj, auto* out) { mlp.Forward(p.data(), xj, out); },
                       Eigen::VectorXd(x.col(j)), 3);
    const Eigen::MatrixXd ref = jac * v.middleCols(k * j, k);
    EXPECT_LT(ScaledError(t.middleCols(k * j, k), ref), kGradTol) << j;
  }
}

TEST_P(MlpTest, BackwardPerGroupMatchesFullJetReference) {
  const testing::ThreadCountGuard guard;  // the test sets the thread count
  const Mlp mlp(SmallOptions(GetParam().first, GetParam().second));
  const auto p = Params(mlp, 5);
  const Eigen::MatrixXd x = RandomMatrix(5, kN, 10);
  const Eigen::MatrixXd dy = RandomMatrix(3, kN, 11);
  MlpCache cache;
  mlp.ForwardBatch(p.data(), x, &cache, nullptr);
  Eigen::MatrixXd dp, dx;
  mlp.Backward(p.data(), cache, dy, kGroups, &dp, &dx);
  const int G = static_cast<int>(kGroups.size()) - 1;
  ASSERT_EQ(dp.rows(), mlp.NumParameters());
  ASSERT_EQ(dp.cols(), G);
  const Eigen::VectorXd pv = Eigen::Map<const Eigen::VectorXd>(p.data(), p.size());
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(mlp.NumParameters(), G);
  for (int g = 0; g < G; ++g) {
    for (int j = kGroups[g]; j < kGroups[g + 1]; ++j) {
      // Full-Jet reference: Jets over all weights (T = P = Jet).
      const Eigen::MatrixXd jac = JetJacobian<32>(
          [&](const auto* pj, auto* out) {
            using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
            J xj[5];
            for (int i = 0; i < 5; ++i) xj[i] = J(x(i, j));
            mlp.Forward(pj, xj, out);
          },
          pv, 3);
      ref.col(g) += jac.transpose() * dy.col(j);
    }
  }
  EXPECT_LT(ScaledError(dp, ref), kGradTol);
  EXPECT_EQ(dp.col(1).norm(), 0.0);  // the empty group
  // One group over all grouped samples (split across threads internally)
  // equals the sum of the per-group columns.
  for (const int threads : {1, 2, 3}) {
    SetNumThreads(threads);
    Eigen::MatrixXd whole;
    mlp.Backward(p.data(), cache, dy, {0, kGroups.back()}, &whole, nullptr);
    EXPECT_LT(ScaledError(whole.col(0), ref.rowwise().sum()), kGradTol) << threads;
  }
  SetNumThreads(2);
  for (int j = 0; j < kN; ++j) {
    const Eigen::MatrixXd jac =
        JetJacobian<5>([&](const auto* xj, auto* out) { mlp.Forward(p.data(), xj, out); },
                       Eigen::VectorXd(x.col(j)), 3);
    EXPECT_LT(ScaledError(dx.col(j), jac.transpose() * dy.col(j)), kGradTol) << j;
  }
}

TEST_P(MlpTest, BackwardOfTangentMatchesJetReference) {
  const Mlp mlp(SmallOptions(GetParam().first, GetParam().second));
  const auto p = Params(mlp, 6);
  const Eigen::MatrixXd x = RandomMatrix(5, kN, 12);
  const Eigen::MatrixXd v = RandomMatrix(5, kN, 13);
  const Eigen::MatrixXd c = RandomMatrix(3, kN, 14);
  MlpCache cache;
  mlp.ForwardBatch(p.data(), x, &cache, nullptr);
  Eigen::MatrixXd dp, dx, dv;
  mlp.BackwardOfTangent(p.data(), cache, v, c, kGroups, &dp, &dx, &dv);
  const int G = static_cast<int>(kGroups.size()) - 1;
  const Eigen::VectorXd pv = Eigen::Map<const Eigen::VectorXd>(p.data(), p.size());
  // Reference: S_j = c_j^T (d out / dx) v_j through dual numbers x + eps v,
  // differentiated with Jets over all weights (or over x and v).
  auto tangent_s = [&](int j, const auto* pj, const auto* xj, const auto* vj, auto* s) {
    using J = std::remove_const_t<std::remove_pointer_t<decltype(xj)>>;
    Dual<J> xd[5], out[3];
    for (int i = 0; i < 5; ++i) xd[i] = Dual<J>(xj[i], vj[i]);
    mlp.Forward(pj, xd, out);
    s[0] = J(0.0);
    for (int o = 0; o < 3; ++o) s[0] += c(o, j) * out[o].tangent;
  };
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(mlp.NumParameters(), G);
  for (int g = 0; g < G; ++g) {
    for (int j = kGroups[g]; j < kGroups[g + 1]; ++j) {
      ref.col(g) += JetJacobian<32>(
                        [&](const auto* pj, auto* s) {
                          using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
                          J xj[5], vj[5];
                          for (int i = 0; i < 5; ++i) xj[i] = J(x(i, j)), vj[i] = J(v(i, j));
                          tangent_s(j, pj, xj, vj, s);
                        },
                        pv, 1)
                        .transpose();
    }
  }
  EXPECT_LT(ScaledError(dp, ref), kGradTol);
  for (int j = 0; j < kN; ++j) {
    Eigen::VectorXd xv(10);
    xv << x.col(j), v.col(j);
    const Eigen::MatrixXd jac = JetJacobian<10>(
        [&](const auto* z, auto* s) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(z)>>;
          std::vector<J> pj(p.begin(), p.end());
          tangent_s(j, pj.data(), z, z + 5, s);
        },
        xv, 1);
    EXPECT_LT(ScaledError(dx.col(j), jac.leftCols(5).transpose()), kGradTol) << j;
    EXPECT_LT(ScaledError(dv.col(j), jac.rightCols(5).transpose()), kGradTol) << j;
  }
}

INSTANTIATE_TEST_SUITE_P(Activations, MlpTest,
                         ::testing::Values(std::make_pair(Activation::kSoftplus, 100.0),
                                           std::make_pair(Activation::kSoftplus, 3.0),
                                           std::make_pair(Activation::kRelu, 0.0 + 1.0)));

// Analytic cost function: residual = MLP(params, x) with Jacobians from the
// batched backward pass (one reverse pass per residual row), checked against
// numeric differentiation by ceres::GradientChecker.
class MlpCost : public ceres::CostFunction {
 public:
  explicit MlpCost(const Mlp* mlp) : mlp_(mlp) {
    set_num_residuals(mlp->OutputDim());
    mutable_parameter_block_sizes()->push_back(mlp->NumParameters());
    mutable_parameter_block_sizes()->push_back(mlp->InputDim());
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::MatrixXd x = Eigen::Map<const Eigen::VectorXd>(parameters[1], mlp_->InputDim());
    MlpCache cache;
    Eigen::MatrixXd y;
    mlp_->ForwardBatch(parameters[0], x, &cache, &y);
    for (int r = 0; r < mlp_->OutputDim(); ++r) residuals[r] = y(r, 0);
    if (jacobians == nullptr) return true;
    for (int r = 0; r < mlp_->OutputDim(); ++r) {
      Eigen::MatrixXd dy = Eigen::MatrixXd::Zero(mlp_->OutputDim(), 1);
      dy(r, 0) = 1.0;
      Eigen::MatrixXd dp, dx;
      mlp_->Backward(parameters[0], cache, dy, {0, 1}, &dp, &dx);
      if (jacobians[0] != nullptr) {
        for (int i = 0; i < mlp_->NumParameters(); ++i)
          jacobians[0][r * mlp_->NumParameters() + i] = dp(i, 0);
      }
      if (jacobians[1] != nullptr) {
        for (int i = 0; i < mlp_->InputDim(); ++i)
          jacobians[1][r * mlp_->InputDim() + i] = dx(i, 0);
      }
    }
    return true;
  }

 private:
  const Mlp* mlp_;
};

TEST(Mlp, GradientCheckerAgreesWithBackward) {
  for (const double beta : {3.0, 100.0}) {
    MlpOptions o = SmallOptions(Activation::kSoftplus, beta);
    o.width = 6;
    const Mlp mlp(o);
    auto p = Params(mlp, 21);
    Eigen::VectorXd x = RandomMatrix(5, 1, 22).col(0);
    auto cost = std::make_unique<MlpCost>(&mlp);
    ceres::NumericDiffOptions numeric;
    // Sharp softplus (beta = 100): a small initial Ridders step avoids false
    // failures (docs/design.md).
    numeric.ridders_relative_initial_step_size = 1e-4;
    const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
    ceres::GradientChecker checker(cost.get(), no_manifolds, numeric);
    ceres::GradientChecker::ProbeResults results;
    const double* blocks[2] = {p.data(), x.data()};
    // 1e-7: Ridders extrapolation is accurate to ~1e-9 on these smooth
    // functions; the analytic side is exact.
    const bool ok = checker.Probe(blocks, 1e-7, &results);
    if (beta < 10.0) {
      EXPECT_TRUE(ok) << results.error_log;
    } else {
      // With beta = 100 switched-off units have derivatives ~1e-11 whose
      // per-entry relative error (GradientChecker's only criterion) is
      // dominated by ~1e-14 absolute differencing noise: compare against the
      // scale of each Jacobian block instead.
      for (int b = 0; b < 2; ++b) {
        EXPECT_LT(ScaledError(results.jacobians[b], results.numeric_jacobians[b]), 1e-7)
            << "block " << b;
      }
    }
  }
}

TEST(Mlp, SoftplusFiniteForLargeInputs) {
  for (double z : {1e4, -1e4, 1e300, -1e300, 0.0}) {
    const double s = mlp_internal::Softplus(z, 100.0);
    EXPECT_TRUE(std::isfinite(s)) << z;
    if (z > 0) {
      EXPECT_EQ(s, z);
    }
    if (z < 0) {
      EXPECT_EQ(s, 0.0);
    }
    ceres::Jet<double, 1> zj(z, 0);
    const auto sj = mlp_internal::Softplus(zj, 100.0);
    EXPECT_TRUE(std::isfinite(sj.a) && std::isfinite(sj.v[0])) << z;
    EXPECT_NEAR(sj.v[0], z > 0 ? 1.0 : 0.0, z == 0.0 ? 0.5 + 1e-12 : 1e-300);
  }
  EXPECT_NEAR(mlp_internal::Softplus(0.0, 100.0), std::log(2.0) / 100.0, 1e-17);
  // Through whole networks, batched and single point, inputs +-1e4.
  const Mlp mlp(SmallOptions(Activation::kSoftplus, 100.0));
  const auto p = Params(mlp, 30);
  Eigen::MatrixXd x = 1e4 * RandomMatrix(5, 8, 31).array().sign().matrix();
  MlpCache cache;
  Eigen::MatrixXd y, dp, dx, t;
  mlp.ForwardBatch(p.data(), x, &cache, &y);
  mlp.ForwardTangents(p.data(), cache, Eigen::MatrixXd::Ones(5, 8), 1, &t);
  mlp.Backward(p.data(), cache, Eigen::MatrixXd::Ones(3, 8), {0, 8}, &dp, &dx);
  EXPECT_TRUE(y.allFinite() && t.allFinite() && dp.allFinite() && dx.allFinite());
  for (int j = 0; j < 8; ++j) {
    Eigen::Vector3d ref;
    mlp.Forward(p.data(), x.col(j).data(), ref.data());
    EXPECT_TRUE(ref.allFinite());
    EXPECT_LT((ref - y.col(j)).norm(), 1e-12 * std::max(1.0, ref.norm()));
  }
}

TEST(Mlp, InitializationIsDeterministic) {
  const Mlp mlp(SmallOptions(Activation::kSoftplus));
  std::vector<double> a(mlp.NumParameters()), b(mlp.NumParameters()), c(mlp.NumParameters());
  mlp.InitializeDefault(7, a.data());
  mlp.InitializeDefault(7, b.data());
  mlp.InitializeDefault(8, c.data());
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  const double limit = std::sqrt(6.0 / (5 + 8));
  for (int i = 0; i < 40; ++i) EXPECT_LE(std::abs(a[i]), limit);
}

TEST(Mlp, ParallelResultsAreDeterministic) {
  MlpOptions o = SmallOptions(Activation::kSoftplus);
  o.width = 32;
  const Mlp mlp(o);
  const auto p = Params(mlp, 40);
  const Eigen::MatrixXd x = RandomMatrix(5, 1000, 41);
  const Eigen::MatrixXd dy = RandomMatrix(3, 1000, 42);
  std::vector<int> groups;
  for (int g = 0; g <= 1000; g += 40) groups.push_back(g);
  Eigen::MatrixXd first;
  for (int rep = 0; rep < 2; ++rep) {
    MlpCache cache;
    Eigen::MatrixXd dp;
    mlp.ForwardBatch(p.data(), x, &cache, nullptr);
    mlp.Backward(p.data(), cache, dy, groups, &dp, nullptr);
    if (rep == 0) {
      first = dp;
    } else {
      EXPECT_EQ((dp - first).cwiseAbs().maxCoeff(), 0.0);
    }
  }
}

}  // namespace
}  // namespace banmo
