#include "banmo/field/canonical_field.h"

#include <gtest/gtest.h>

#include <random>

#include "banmo/util/dual.h"
#include "banmo/util/error.h"
#include "field_test_util.h"

namespace banmo {
namespace {

using test::JetJacobian;
using test::ScaledError;

// Batched and templated paths are both exact; they differ only in rounding
// order (see mlp_test.cc), so values agree to 1e-12 and derivatives to 1e-9
// relative to their scale.
constexpr double kValueTol = 1e-12;
constexpr double kGradTol = 1e-9;

CanonicalFieldOptions SmallOptions() {
  CanonicalFieldOptions o;
  o.position_encoding.num_bands = 3;
  o.sdf_width = 12;
  o.sdf_layers = 2;
  o.geometry_feature_dim = 4;
  o.color_width = 8;
  o.color_layers = 1;
  o.use_view_direction = true;
  o.view_encoding.num_bands = 1;
  o.appearance_code_dim = 2;
  o.embedding_width = 8;
  o.embedding_layers = 1;
  return o;
}

struct Fixture {
  explicit Fixture(const CanonicalFieldOptions& o, int n = 23) : field(o) {
    sdf.resize(field.SdfParameterSize());
    color.resize(field.ColorParameterSize());
    emb.resize(field.EmbeddingParameterSize());
    field.InitializeParameters(5, sdf.data(), color.data(), emb.data());
    // Perturb every weight (the sphere init has exact zeros on the Fourier
    // features), so all paths are exercised at a generic point.
    std::mt19937 rng(6);
    std::uniform_real_distribution<double> u(-0.1, 0.1);
    for (double& v : sdf) v += u(rng);
    for (double& v : color) v += u(rng);
    for (double& v : emb) v += u(rng);
    std::uniform_real_distribution<double> w(-1.0, 1.0);
    batch.x.resize(3, n);
    batch.view_dir.resize(3, n);
    batch.appearance.resize(o.appearance_code_dim, n);
    for (int j = 0; j < n; ++j) {
      for (int c = 0; c < 3; ++c) batch.x(c, j) = w(rng), batch.view_dir(c, j) = w(rng);
      batch.view_dir.col(j).normalize();
      for (int a = 0; a < o.appearance_code_dim; ++a) batch.appearance(a, j) = w(rng);
    }
  }
  CanonicalField field;
  std::vector<double> sdf, color, emb;
  FieldBatch batch;
};

const std::vector<int> kGroups = {0, 4, 4, 11, 20};  // samples 20..22 in no group

TEST(CanonicalField, ForwardBatchMatchesTemplatedWithInputJacobians) {
  Fixture f(SmallOptions());
  const CanonicalField& field = f.field;
  field.ForwardBatch(f.sdf.data(), f.color.data(), &f.batch, true);
  const int A = field.AppearanceCodeDim();
  for (int j = 0; j < f.batch.size(); ++j) {
    double sdf, rgb[3];
    field.Evaluate(f.sdf.data(), f.color.data(), f.batch.x.col(j).data(),
                   f.batch.view_dir.col(j).data(), f.batch.appearance.col(j).data(), &sdf, rgb);
    EXPECT_NEAR(f.batch.sdf[j], sdf, kValueTol);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(f.batch.rgb(c, j), rgb[c], kValueTol);
    for (int c = 0; c < 3; ++c) {
      EXPECT_GT(rgb[c], 0.0);
      EXPECT_LT(rgb[c], 1.0);
    }
    // Jets over [x, view_dir, appearance] -> [sdf, rgb].
    Eigen::VectorXd z(6 + A);
    z << f.batch.x.col(j), f.batch.view_dir.col(j), f.batch.appearance.col(j);
    const Eigen::MatrixXd jac = JetJacobian<8>(
        [&](const auto* zj, auto* out) {
          field.Evaluate(f.sdf.data(), f.color.data(), zj, zj + 3, zj + 6, out, out + 1);
        },
        z, 4);
    EXPECT_LT(ScaledError(f.batch.dsdf_dx.col(j).transpose(), jac.block(0, 0, 1, 3)), kGradTol);
    EXPECT_LT(ScaledError(f.batch.drgb_dx.middleCols(3 * j, 3), jac.block(1, 0, 3, 3)), kGradTol);
    EXPECT_LT(ScaledError(f.batch.drgb_dview.middleCols(3 * j, 3), jac.block(1, 3, 3, 3)),
              kGradTol);
    EXPECT_LT(ScaledError(f.batch.drgb_dappearance.middleCols(A * j, A), jac.block(1, 6, 3, A)),
              kGradTol);
  }
}

TEST(CanonicalField, ForwardSdfBatchMatchesForwardBatch) {
  Fixture f(SmallOptions());
  f.field.ForwardBatch(f.sdf.data(), f.color.data(), &f.batch, true);
  FieldBatch b;
  b.x = f.batch.x;
  f.field.ForwardSdfBatch(f.sdf.data(), &b, true);
  EXPECT_LT((b.sdf - f.batch.sdf).cwiseAbs().maxCoeff(), kValueTol);
  EXPECT_LT((b.feature - f.batch.feature).cwiseAbs().maxCoeff(), kValueTol);
  // Reverse-mode gradient vs forward-tangent gradient.
  EXPECT_LT(ScaledError(b.dsdf_dx, f.batch.dsdf_dx), kGradTol);
  Eigen::Matrix3Xd c = Eigen::Matrix3Xd::Ones(3, b.size());
  Eigen::MatrixXd dp1, dp2;
  f.field.SdfGradientBackward(f.sdf.data(), b, c, kGroups, &dp1, nullptr);
  f.field.SdfGradientBackward(f.sdf.data(), f.batch, c, kGroups, &dp2, nullptr);
  EXPECT_LT(ScaledError(dp1, dp2), kValueTol);
}

// ForwardColorBatch on some columns (the ray pipeline's samples that count):
// at those columns rgb and its Jacobians are ForwardBatch's, elsewhere 0;
// BackwardBatch with d_rgb at those columns gives ForwardBatch's gradients
// (per group, and wrt the points) for the same d_rgb, the colour groups
// mapped to the columns. Rounding: the same operations on the same values,
// so to kValueTol; none of the columns (empty) leaves the SDF terms alone.
TEST(CanonicalField, ColorOnSomeColumnsMatchesForwardBatch) {
  Fixture f(SmallOptions());
  const CanonicalField& field = f.field;
  const int n = f.batch.size();
  const int A = field.AppearanceCodeDim();
  field.ForwardBatch(f.sdf.data(), f.color.data(), &f.batch, true);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd d_sdf(n);
  Eigen::Matrix3Xd d_rgb(3, n);
  for (int j = 0; j < n; ++j) {
    d_sdf[j] = u(rng);
    for (int c = 0; c < 3; ++c) d_rgb(c, j) = u(rng);
  }
  // Columns in every group, none in one, and past the last group (20..22).
  for (const std::vector<int>& columns :
       {std::vector<int>{1, 2, 5, 9, 10, 17, 21}, std::vector<int>{}}) {
    FieldBatch b;
    b.x = f.batch.x;
    b.view_dir = f.batch.view_dir;
    b.appearance = f.batch.appearance;
    field.ForwardGeometryBatch(f.sdf.data(), &b, true);
    field.ForwardColorBatch(f.color.data(), columns, &b, true);
    EXPECT_EQ(b.color_columns, columns);
    EXPECT_LT((b.sdf - f.batch.sdf).cwiseAbs().maxCoeff(), kValueTol);
    EXPECT_LT((b.dsdf_dx - f.batch.dsdf_dx).cwiseAbs().maxCoeff(), kValueTol);
    Eigen::Matrix3Xd d_rgb_on = Eigen::Matrix3Xd::Zero(3, n);
    std::vector<char> on(n, 0);
    for (int j : columns) on[j] = 1, d_rgb_on.col(j) = d_rgb.col(j);
    for (int j = 0; j < n; ++j) {
      const double keep = on[j] ? 1.0 : 0.0;
      EXPECT_LT((b.rgb.col(j) - keep * f.batch.rgb.col(j)).cwiseAbs().maxCoeff(), kValueTol) << j;
      EXPECT_LT((b.drgb_dx.middleCols(3 * j, 3) - keep * f.batch.drgb_dx.middleCols(3 * j, 3))
                    .cwiseAbs()
                    .maxCoeff(),
                kValueTol)
          << j;
      EXPECT_LT((b.drgb_dview.middleCols(3 * j, 3) - keep * f.batch.drgb_dview.middleCols(3 * j, 3))
                    .cwiseAbs()
                    .maxCoeff(),
                kValueTol)
          << j;
      EXPECT_LT((b.drgb_dappearance.middleCols(A * j, A) -
                 keep * f.batch.drgb_dappearance.middleCols(A * j, A))
                    .cwiseAbs()
                    .maxCoeff(),
                kValueTol)
          << j;
    }
    Eigen::MatrixXd dps, dpc, dps_ref, dpc_ref;
    Eigen::Matrix3Xd dx, dx_ref;
    field.BackwardBatch(f.sdf.data(), f.color.data(), b, d_sdf, d_rgb, kGroups, &dps, &dpc, &dx);
    field.BackwardBatch(f.sdf.data(), f.color.data(), f.batch, d_sdf, d_rgb_on, kGroups, &dps_ref,
                        &dpc_ref, &dx_ref);
    EXPECT_LT(ScaledError(dps, dps_ref), kValueTol) << columns.size();
    EXPECT_LT(ScaledError(dpc, dpc_ref), kValueTol) << columns.size();
    EXPECT_LT(ScaledError(dx, dx_ref), kValueTol) << columns.size();
    if (columns.empty()) {
      EXPECT_EQ(dpc.cwiseAbs().maxCoeff(), 0.0);
    }
  }
}

TEST(CanonicalField, BackwardBatchPerGroupMatchesFullJetReference) {
  for (const bool view : {true, false}) {
    CanonicalFieldOptions o = SmallOptions();
    o.use_view_direction = view;
    o.appearance_code_dim = view ? 2 : 0;
    Fixture f(o);
    const CanonicalField& field = f.field;
    field.ForwardBatch(f.sdf.data(), f.color.data(), &f.batch, false);
    const int n = f.batch.size();
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Eigen::VectorXd d_sdf(n);
    Eigen::Matrix3Xd d_rgb(3, n);
    for (int j = 0; j < n; ++j) {
      d_sdf[j] = u(rng);
      for (int c = 0; c < 3; ++c) d_rgb(c, j) = u(rng);
    }
    Eigen::MatrixXd dps, dpc;
    Eigen::Matrix3Xd dx;
    field.BackwardBatch(f.sdf.data(), f.color.data(), f.batch, d_sdf, d_rgb, kGroups, &dps, &dpc,
                        &dx);
    const int Ps = field.SdfParameterSize(), Pc = field.ColorParameterSize();
    Eigen::VectorXd all(Ps + Pc);
    all << Eigen::Map<const Eigen::VectorXd>(f.sdf.data(), Ps),
        Eigen::Map<const Eigen::VectorXd>(f.color.data(), Pc);
    const int G = static_cast<int>(kGroups.size()) - 1;
    Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(Ps + Pc, G);
    for (int g = 0; g < G; ++g) {
      for (int j = kGroups[g]; j < kGroups[g + 1]; ++j) {
        const Eigen::MatrixXd jac = JetJacobian<32>(
            [&](const auto* pj, auto* out) {
              using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
              J x[3], v[3], a[2];
              for (int c = 0; c < 3; ++c)
                x[c] = J(f.batch.x(c, j)), v[c] = J(f.batch.view_dir(c, j));
              for (int c = 0; c < o.appearance_code_dim; ++c) a[c] = J(f.batch.appearance(c, j));
              field.Evaluate(pj, pj + Ps, x, v, a, out, out + 1);
            },
            all, 4);
        Eigen::Vector4d cot(d_sdf[j], d_rgb(0, j), d_rgb(1, j), d_rgb(2, j));
        ref.col(g) += jac.transpose() * cot;
      }
    }
    EXPECT_LT(ScaledError(dps, ref.topRows(Ps)), kGradTol) << view;
    EXPECT_LT(ScaledError(dpc, ref.bottomRows(Pc)), kGradTol) << view;
    for (int j = 0; j < n; ++j) {
      const Eigen::MatrixXd jac = JetJacobian<3>(
          [&](const auto* xj, auto* out) {
            using J = std::remove_const_t<std::remove_pointer_t<decltype(xj)>>;
            J v[3], a[2];
            for (int c = 0; c < 3; ++c) v[c] = J(f.batch.view_dir(c, j));
            for (int c = 0; c < o.appearance_code_dim; ++c) a[c] = J(f.batch.appearance(c, j));
            field.Evaluate(f.sdf.data(), f.color.data(), xj, v, a, out, out + 1);
          },
          Eigen::VectorXd(f.batch.x.col(j)), 4);
      Eigen::Vector4d cot(d_sdf[j], d_rgb(0, j), d_rgb(1, j), d_rgb(2, j));
      EXPECT_LT(ScaledError(dx.col(j), jac.transpose() * cot), kGradTol) << j;
    }
  }
}

TEST(CanonicalField, SdfGradientBackwardMatchesJetReference) {
  Fixture f(SmallOptions());
  const CanonicalField& field = f.field;
  field.ForwardBatch(f.sdf.data(), f.color.data(), &f.batch, true);
  const int n = f.batch.size();
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3Xd c(3, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < 3; ++i) c(i, j) = u(rng);
  Eigen::MatrixXd dp;
  Eigen::Matrix3Xd dx;
  field.SdfGradientBackward(f.sdf.data(), f.batch, c, kGroups, &dp, &dx);
  // Same result without cached encoding Jacobians.
  FieldBatch plain = f.batch;
  field.ForwardBatch(f.sdf.data(), f.color.data(), &plain, false);
  Eigen::MatrixXd dp2;
  Eigen::Matrix3Xd dx2;
  field.SdfGradientBackward(f.sdf.data(), plain, c, kGroups, &dp2, &dx2);
  EXPECT_EQ((dp - dp2).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ((dx - dx2).cwiseAbs().maxCoeff(), 0.0);

  // Reference: S_j = c_j . grad sdf(x_j) = tangent of sdf at x_j + eps c_j.
  auto s_of = [&](int j, const auto* pj, const auto* xj, auto* s) {
    using J = std::remove_const_t<std::remove_pointer_t<decltype(xj)>>;
    Dual<J> xd[3], sdf;
    for (int i = 0; i < 3; ++i) xd[i] = Dual<J>(xj[i], J(c(i, j)));
    field.EvaluateSdf(pj, xd, &sdf, static_cast<Dual<J>*>(nullptr));
    s[0] = sdf.tangent;
  };
  const int Ps = field.SdfParameterSize();
  const Eigen::VectorXd pv = Eigen::Map<const Eigen::VectorXd>(f.sdf.data(), Ps);
  const int G = static_cast<int>(kGroups.size()) - 1;
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(Ps, G);
  for (int g = 0; g < G; ++g) {
    for (int j = kGroups[g]; j < kGroups[g + 1]; ++j) {
      ref.col(g) += JetJacobian<32>(
                        [&](const auto* pj, auto* s) {
                          using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
                          J x[3];
                          for (int i = 0; i < 3; ++i) x[i] = J(f.batch.x(i, j));
                          s_of(j, pj, x, s);
                        },
                        pv, 1)
                        .transpose();
    }
  }
  EXPECT_LT(ScaledError(dp, ref), kGradTol);
  for (int j = 0; j < n; ++j) {
    const Eigen::MatrixXd jac = JetJacobian<3>(
        [&](const auto* xj, auto* s) {
          using J = std::remove_const_t<std::remove_pointer_t<decltype(xj)>>;
          std::vector<J> pj(f.sdf.begin(), f.sdf.end());
          s_of(j, pj.data(), xj, s);
        },
        Eigen::VectorXd(f.batch.x.col(j)), 1);
    EXPECT_LT(ScaledError(dx.col(j), jac.transpose()), kGradTol) << j;
  }
}

TEST(CanonicalField, EmbeddingBatchMatchesTemplated) {
  Fixture f(SmallOptions());
  const CanonicalField& field = f.field;
  EmbeddingBatch eb;
  eb.x = f.batch.x;
  field.ForwardEmbeddingBatch(f.emb.data(), &eb, true);
  const int n = eb.size();
  ASSERT_EQ(eb.psi.rows(), 16);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd d_psi(16, n);
  for (int j = 0; j < n; ++j)
    for (int r = 0; r < 16; ++r) d_psi(r, j) = u(rng);
  Eigen::MatrixXd dp;
  Eigen::Matrix3Xd dx;
  field.BackwardEmbeddingBatch(f.emb.data(), eb, d_psi, kGroups, &dp, &dx);
  const int P = field.EmbeddingParameterSize();
  const Eigen::VectorXd pv = Eigen::Map<const Eigen::VectorXd>(f.emb.data(), P);
  const int G = static_cast<int>(kGroups.size()) - 1;
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(P, G);
  for (int j = 0; j < n; ++j) {
    double psi[16];
    field.EvaluateEmbedding(f.emb.data(), eb.x.col(j).data(), psi);
    for (int r = 0; r < 16; ++r) EXPECT_NEAR(eb.psi(r, j), psi[r], kValueTol);
    const Eigen::MatrixXd jx = JetJacobian<3>(
        [&](const auto* xj, auto* out) { field.EvaluateEmbedding(f.emb.data(), xj, out); },
        Eigen::VectorXd(eb.x.col(j)), 16);
    EXPECT_LT(ScaledError(eb.dpsi_dx.middleCols(3 * j, 3), jx), kGradTol);
    EXPECT_LT(ScaledError(dx.col(j), jx.transpose() * d_psi.col(j)), kGradTol);
    for (int g = 0; g < G; ++g) {
      if (j < kGroups[g] || j >= kGroups[g + 1]) continue;
      const Eigen::MatrixXd jp = JetJacobian<32>(
          [&](const auto* pj, auto* out) {
            using J = std::remove_const_t<std::remove_pointer_t<decltype(pj)>>;
            J x[3];
            for (int i = 0; i < 3; ++i) x[i] = J(eb.x(i, j));
            field.EvaluateEmbedding(pj, x, out);
          },
          pv, 16);
      ref.col(g) += jp.transpose() * d_psi.col(j);
    }
  }
  EXPECT_LT(ScaledError(dp, ref), kGradTol);
}

// Geometric initialisation with the default options: sdf(X) ~= |X| - r.
TEST(CanonicalField, GeometricInitIsSphere) {
  const CanonicalFieldOptions o;
  const CanonicalField field(o);
  std::vector<double> sdf(field.SdfParameterSize()), color(field.ColorParameterSize()),
      emb(field.EmbeddingParameterSize());
  double worst = 0.0, sum = 0.0, worst_grad = 0.0, max_weight = 0.0;
  constexpr int kSeeds = 5, kN = 2000;
  for (uint32_t seed = 0; seed < kSeeds; ++seed) {
    field.InitializeParameters(seed, sdf.data(), color.data(), emb.data());
    std::mt19937 rng(100 + seed);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    FieldBatch b;
    b.x.resize(3, kN);
    for (int j = 0; j < kN;) {
      const Eigen::Vector3d p(u(rng), u(rng), u(rng));
      if (p.norm() < 1.5) b.x.col(j++) = p;
    }
    b.view_dir = Eigen::Matrix3Xd::Zero(3, kN);
    b.view_dir.row(2).setOnes();
    b.appearance = Eigen::MatrixXd::Zero(o.appearance_code_dim, kN);
    field.ForwardBatch(sdf.data(), color.data(), &b, true);
    for (int j = 0; j < kN; ++j) {
      const double err = std::abs(b.sdf[j] - (b.x.col(j).norm() - o.init_sphere_radius));
      worst = std::max(worst, err);
      sum += err;
      if (b.x.col(j).norm() > 0.2) {
        worst_grad = std::max(worst_grad, std::abs(b.dsdf_dx.col(j).norm() - 1.0));
      }
    }
    EXPECT_TRUE(b.rgb.allFinite());
    // The calibrated output row stays at the scale of SAL's (sqrt(pi/width)
    // ~ 0.22 per weight), not a wild least-squares fit.
    const Mlp& m = field.sdf_mlp();
    const int last = m.NumLinearLayers() - 1;
    const Eigen::Map<const Eigen::VectorXd> w(sdf.data() + m.WeightOffset(last), o.sdf_width);
    max_weight = std::max(max_weight, w.cwiseAbs().maxCoeff());
  }
  std::printf("largest calibrated output weight: %.3f\n", max_weight);
  EXPECT_LT(max_weight, 2.0);
  const double mean = sum / (kSeeds * kN);
  RecordProperty("max_abs_error", std::to_string(worst));
  std::printf(
      "geometric init (width %d, %d layers, 5 seeds x %d points, |X| < 1.5): "
      "mean |sdf - (|X| - r)| = %.4f, max = %.4f, max ||grad| - 1| (|X| > 0.2) = %.3f\n",
      o.sdf_width, o.sdf_layers, kN, mean, worst, worst_grad);
  // Measured: mean 0.017, max 0.10 (near the cone tip at X = 0 and the rim).
  EXPECT_LT(mean, 0.03);
  EXPECT_LT(worst, 0.15);
  EXPECT_LT(worst_grad, 0.3);
}

TEST(CanonicalField, OptionsCheck) {
  auto error = [](const CanonicalFieldOptions& o) -> std::string {
    try {
      o.Check();
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  CanonicalFieldOptions o;
  EXPECT_EQ(error(o), "");
  o.position_encoding.include_input = false;
  EXPECT_NE(error(o).find("model.field.position_encoding.include_input"), std::string::npos)
      << error(o);
  o = CanonicalFieldOptions();
  o.geometry_feature_dim = 0;
  o.use_view_direction = false;
  o.appearance_code_dim = 0;
  EXPECT_EQ(error(o).rfind("model.field: the colour MLP has no input", 0), 0u) << error(o);
  o = CanonicalFieldOptions();
  o.init_sphere_radius = 0.0;
  EXPECT_NE(error(o).find("model.field.init_sphere_radius"), std::string::npos) << error(o);
  o = CanonicalFieldOptions();
  o.position_encoding.num_bands = -2;
  EXPECT_EQ(error(o), "model.field.position_encoding.num_bands must be in [0, 32], got -2");
  try {
    o.Check("options.field");  // the model file's key
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("options.field.position_encoding.num_bands", 0), 0u);
  }
}

}  // namespace
}  // namespace banmo
