#include "banmo/field/embedding_match.h"

#include <gtest/gtest.h>

#include <random>

#include "../common/thread_count_guard.h"
#include "banmo/util/parallel.h"
#include "field_test_util.h"

namespace banmo {
namespace {

using test::JetJacobian;
using test::ScaledError;

// A "realistic" canonical embedding: smooth random Fourier features of the
// canonical position (the CSE stand-in the synthetic generator uses is a
// smooth random embedding of the surface point as well).
struct Scene {
  explicit Scene(uint32_t seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.5);
    std::uniform_real_distribution<double> u(0.0, 2.0 * M_PI);
    for (int r = 0; r < 16; ++r) {
      for (int c = 0; c < 3; ++c) freq(r, c) = n(rng);
      phase[r] = u(rng);
    }
  }
  Eigen::VectorXd Psi(const Eigen::Vector3d& x) const {
    return (freq * x + phase).array().sin().matrix();
  }
  Eigen::Matrix<double, 16, 3> freq;
  Eigen::Matrix<double, 16, 1> phase;
};

// M = 16^3 = 4096 grid points in [-1, 1]^3.
void MakeGrid(const Scene& scene, Eigen::Matrix3Xd* grid, Eigen::MatrixXd* psi) {
  constexpr int kSide = 16;
  grid->resize(3, kSide * kSide * kSide);
  psi->resize(16, kSide * kSide * kSide);
  int m = 0;
  for (int i = 0; i < kSide; ++i)
    for (int j = 0; j < kSide; ++j)
      for (int k = 0; k < kSide; ++k, ++m) {
        grid->col(m) = Eigen::Vector3d(i, j, k) * (2.0 / (kSide - 1)) - Eigen::Vector3d::Ones();
        psi->col(m) = scene.Psi(grid->col(m));
      }
}

TEST(EmbeddingMatch, MatchEqualsSoftArgmaxOnItsCandidates) {
  const Scene scene(1);
  Eigen::Matrix3Xd grid;
  Eigen::MatrixXd psi;
  MakeGrid(scene, &grid, &psi);
  EmbeddingMatcherOptions o;
  o.exact = true;
  EmbeddingMatcher matcher(o);
  matcher.Build(grid, psi);
  const Eigen::VectorXd f = scene.Psi(Eigen::Vector3d(0.2, -0.3, 0.5));
  MatchResult r;
  matcher.Match(f, 32, &r);
  ASSERT_EQ(r.indices.size(), 32u);
  EXPECT_NEAR(r.weights.sum(), 1.0, 1e-14);
  for (int k = 1; k < 32; ++k) EXPECT_GE(r.similarity[k - 1], r.similarity[k]);
  Eigen::MatrixXd cand_psi(16, 32);
  Eigen::Matrix3Xd cand_pts(3, 32);
  for (int k = 0; k < 32; ++k) {
    cand_psi.col(k) = psi.col(r.indices[k]);
    cand_pts.col(k) = grid.col(r.indices[k]);
  }
  Eigen::Vector3d x_hat;
  SoftArgmax(f.data(), cand_psi.data(), cand_pts.data(), 32, o.temperature, x_hat.data());
  EXPECT_LT((x_hat - r.x_hat).norm(), 1e-14);
  // The best grid point is the nearest one to the true position (smooth,
  // distinctive embedding).
  EXPECT_LT((grid.col(r.indices[0]) - Eigen::Vector3d(0.2, -0.3, 0.5)).norm(), 0.2);
}

TEST(EmbeddingMatch, HandBackwardMatchesJets) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const double temperature : {5.0, 20.0, 100.0}) {
    constexpr int K = 6;
    Eigen::VectorXd z(16 * (K + 1));  // [feature; psi_0; ...; psi_{K-1}]
    for (int i = 0; i < z.size(); ++i) z[i] = u(rng);
    Eigen::Matrix3Xd pts(3, K);
    for (int k = 0; k < K; ++k)
      for (int c = 0; c < 3; ++c) pts(c, k) = u(rng);
    const Eigen::Vector3d g(u(rng), u(rng), u(rng));
    Eigen::MatrixXd d_psi;
    Eigen::VectorXd d_f;
    double d_tau = 0.0;
    SoftArgmaxBackward(z.data(), z.data() + 16, pts.data(), K, temperature, g.data(), &d_psi, &d_f,
                       &d_tau);
    // Learnable temperature: Jet over tau.
    const Eigen::MatrixXd jac_tau = JetJacobian<1>(
        [&](const auto* tj, auto* out) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(tj)>>;
          std::vector<J> zj(z.data(), z.data() + z.size());
          SoftArgmax(zj.data(), zj.data() + 16, pts.data(), K, tj[0], out);
        },
        Eigen::VectorXd::Constant(1, temperature), 3);
    EXPECT_NEAR(d_tau, (jac_tau.transpose() * g)(0), 1e-9 * std::max(1.0, std::abs(d_tau)));
    const Eigen::MatrixXd jac = JetJacobian<16>(
        [&](const auto* zj, auto* out) {
          SoftArgmax(zj, zj + 16, pts.data(), K, temperature, out);
        },
        z, 3);
    const Eigen::VectorXd ref = jac.transpose() * g;
    // Both exact; 1e-9 relative as for all hand-vs-Jet comparisons.
    EXPECT_LT(ScaledError(d_f, ref.head(16)), 1e-9) << temperature;
    EXPECT_LT(
        ScaledError(Eigen::Map<const Eigen::VectorXd>(d_psi.data(), 16 * K), ref.tail(16 * K)),
        1e-9)
        << temperature;
  }
}

TEST(EmbeddingMatch, ZeroNormFeatureAndEmbeddingAreFinite) {
  constexpr int K = 4;
  Eigen::MatrixXd psi = Eigen::MatrixXd::Random(16, K);
  psi.col(2).setZero();
  Eigen::Matrix3Xd pts = Eigen::Matrix3Xd::Random(3, K);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(16);
  const Eigen::Vector3d g(1.0, -2.0, 0.5);
  for (const Eigen::VectorXd& f : {zero, Eigen::VectorXd(Eigen::VectorXd::Ones(16))}) {
    Eigen::Vector3d x_hat;
    SoftArgmax(f.data(), psi.data(), pts.data(), K, 20.0, x_hat.data());
    EXPECT_TRUE(x_hat.allFinite());
    Eigen::MatrixXd d_psi;
    Eigen::VectorXd d_f;
    SoftArgmaxBackward(f.data(), psi.data(), pts.data(), K, 20.0, g.data(), &d_psi, &d_f);
    EXPECT_TRUE(d_psi.allFinite());
    EXPECT_TRUE(d_f.allFinite());
    ceres::Jet<double, 16> fj[16], pj[16 * K], xj[3];
    for (int i = 0; i < 16; ++i) fj[i] = ceres::Jet<double, 16>(f[i], i);
    for (int i = 0; i < 16 * K; ++i) pj[i] = ceres::Jet<double, 16>(psi.data()[i]);
    SoftArgmax(fj, pj, pts.data(), K, 20.0, xj);
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(ceres::isfinite(xj[c]));
  }
  // Zero feature: all similarities 0, uniform weights, x_hat = centroid.
  Eigen::Vector3d x_hat;
  SoftArgmax(zero.data(), psi.data(), pts.data(), K, 20.0, x_hat.data());
  EXPECT_LT((x_hat - pts.rowwise().mean()).norm(), 1e-15);
  for (const bool exact : {true, false}) {
    EmbeddingMatcherOptions o;
    o.exact = exact;
    EmbeddingMatcher matcher(o);
    matcher.Build(pts, psi);
    MatchResult r;
    matcher.Match(zero, 3, &r);
    EXPECT_TRUE(r.x_hat.allFinite());
    EXPECT_TRUE(r.weights.allFinite());
    EXPECT_NEAR(r.weights.sum(), 1.0, 1e-15);
  }
}

// Match is called concurrently from the ray cost functions' batched pass.
TEST(EmbeddingMatch, ConcurrentMatchesEqualSerial) {
  const testing::ThreadCountGuard guard;  // the test sets the thread count
  const Scene scene(4);
  Eigen::Matrix3Xd grid;
  Eigen::MatrixXd psi;
  MakeGrid(scene, &grid, &psi);
  EmbeddingMatcher matcher;  // FLANN kd-trees
  matcher.Build(grid, psi);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.9, 0.9);
  std::vector<Eigen::VectorXd> features;
  for (int i = 0; i < 300; ++i)
    features.push_back(scene.Psi(Eigen::Vector3d(u(rng), u(rng), u(rng))));
  std::vector<MatchResult> serial(features.size()), parallel(features.size());
  for (size_t i = 0; i < features.size(); ++i) matcher.Match(features[i], 32, &serial[i]);
  SetNumThreads(2);
  ParallelFor(static_cast<int>(features.size()), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) matcher.Match(features[i], 32, &parallel[i]);
  });
  for (size_t i = 0; i < features.size(); ++i) {
    EXPECT_EQ(serial[i].indices, parallel[i].indices);
    EXPECT_EQ(serial[i].x_hat, parallel[i].x_hat);
  }
}

// Truncation error of the top-K soft-argmax against the full softmax over
// all M = 4096 grid points, 200 noisy pixel features, K = 16/32/64,
// temperatures 10/20/50, exact top-K and FLANN kd-trees. Prints the table.
TEST(EmbeddingMatch, TopKTruncationError) {
  const Scene scene(7);
  Eigen::Matrix3Xd grid;
  Eigen::MatrixXd psi;
  MakeGrid(scene, &grid, &psi);
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-0.9, 0.9);
  std::normal_distribution<double> noise(0.0, 0.1);
  constexpr int kFeatures = 200;
  std::vector<Eigen::VectorXd> features;
  for (int i = 0; i < kFeatures; ++i) {
    Eigen::VectorXd f = scene.Psi(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    for (int d = 0; d < 16; ++d) f[d] += noise(rng);
    features.push_back(f);
  }
  const double max_point_norm = grid.colwise().norm().maxCoeff();
  std::printf("top-K soft-argmax vs full softmax, M = %d grid points in [-1,1]^3, %d features\n",
              static_cast<int>(grid.cols()), kFeatures);
  std::printf("%6s %4s %6s %12s %12s %12s %10s\n", "tau", "K", "search", "mean |dX|", "max |dX|",
              "mean tail w", "recall");
  for (const double tau : {10.0, 20.0, 50.0}) {
    for (const bool exact : {true, false}) {
      EmbeddingMatcherOptions o;
      o.temperature = tau;
      o.exact = exact;
      EmbeddingMatcher matcher(o);
      matcher.Build(grid, psi);
      double previous_mean = 1e9;
      for (const int K : {16, 32, 64}) {
        double sum = 0.0, worst = 0.0, tail_sum = 0.0, recall = 0.0;
        for (const Eigen::VectorXd& f : features) {
          MatchResult full, top;
          matcher.MatchFull(f, &full);
          matcher.Match(f, K, &top);
          const double err = (top.x_hat - full.x_hat).norm();
          const double tail = 1.0 - full.weights.head(K).sum();
          sum += err;
          worst = std::max(worst, err);
          tail_sum += tail;
          int hits = 0;
          for (int k = 0; k < K; ++k) {
            hits += std::count(top.indices.begin(), top.indices.end(), full.indices[k]) > 0;
          }
          recall += static_cast<double>(hits) / K;
          if (exact) {
            // |X_K - X_full| <= 2 * tail mass * max |G| (renormalised head
            // minus full sum); a real bound, not a fit.
            EXPECT_LE(err, 2.0 * tail * max_point_norm + 1e-12);
          }
        }
        const double mean = sum / kFeatures;
        std::printf("%6.0f %4d %6s %12.2e %12.2e %12.2e %10.3f\n", tau, K,
                    exact ? "exact" : "flann", mean, worst, tail_sum / kFeatures,
                    recall / kFeatures);
        if (exact) {
          EXPECT_NEAR(recall / kFeatures, 1.0, 1e-12);
          EXPECT_LE(mean, previous_mean);
        } else {
          EXPECT_GT(recall / kFeatures, 0.8);  // approximate search
        }
        previous_mean = mean;
      }
    }
  }
}

}  // namespace
}  // namespace banmo
