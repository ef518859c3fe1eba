// RayBatch::EvaluateGradient (one cotangent row per ray, one MLP backward pass
// per minibatch) against the gradient assembled from the full per-term
// Jacobians: sum over rays and active terms of rho'(|r|^2) J^T r, and against
// ceres::Problem::Evaluate with constant blocks.
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <set>

#include "banmo/losses/ray_batch.h"
#include "common/test_scene.h"
#include "jacobian_test_util.h"

namespace banmo {
namespace {

using Gradient = std::map<const double*, Eigen::VectorXd>;

// Both sides are exact gradients in double precision that differ only in the
// order of summation (c^T J formed before or after the reverse chain, one
// MLP backward over all samples against one per row and ray): they agree to
// rounding, 1e-10 relative to the largest entry of each block.
constexpr double kTolerance = 1e-10;

// Reference: each term's cost function (full Jacobian mode), the robust loss
// applied as Ceres does for the gradient (rho' J^T r) and cost (1/2 rho).
double ReferenceGradient(RayBatch& batch, const RayRobustLosses& robust, Gradient* g) {
  double cost = 0.0;
  for (int r = 0; r < batch.num_rays(); ++r) {
    for (int t = 0; t < kNumRayTerms; ++t) {
      const LossTerm term = static_cast<LossTerm>(t);
      if (!batch.rays()[r].HasTerm(term, batch.options().weights)) continue;
      auto cost_function = batch.MakeCostFunction(r, term);
      const std::vector<double*> params = batch.TermParameterBlocks(r, term);
      const testing::Evaluation e = testing::EvaluateCost(*cost_function, params);
      EXPECT_TRUE(e.ok);
      const double sq = e.residuals.squaredNorm();
      double rho[3] = {sq, 1.0, 0.0};
      if (robust[t] != nullptr) robust[t]->Evaluate(sq, rho);
      cost += 0.5 * rho[0];
      for (size_t i = 0; i < params.size(); ++i) {
        Eigen::VectorXd& sum = (*g)[params[i]];
        if (sum.size() == 0) sum = Eigen::VectorXd::Zero(e.jacobians[i].cols());
        sum += rho[1] * e.jacobians[i].transpose() * e.residuals;
      }
    }
  }
  return cost;
}

void ExpectGradientsEqual(const Gradient& a, const Gradient& b, const Model& model) {
  std::map<const double*, std::string> names;
  model.ForEachBlock([&](const std::string& name, const double* data, int) { names[data] = name; });
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [block, gb] : b) {
    ASSERT_TRUE(a.count(block)) << names[block];
    const Eigen::VectorXd& ga = a.at(block);
    ASSERT_EQ(ga.size(), gb.size()) << names[block];
    const double scale = gb.cwiseAbs().maxCoeff();
    EXPECT_GT(scale, 0.0) << names[block];
    EXPECT_LE((ga - gb).cwiseAbs().maxCoeff(), kTolerance * scale)
        << names[block] << ": scale " << scale;
  }
}

struct Case {
  const char* name;
  int num_bones;
  bool huber;  // Huber(0.1) on rgb, flow and the 3D cycle; others plain
  bool delta_skinning = false;
  bool feature_render_embedding_only = false;
  bool hold_cycle_tau = true;
  // A sharper density than the scene's (SharpenDensityUntilSomeSamplesSkip,
  // tests/common) that leaves some samples of the rgb rays under kMinWarpTau
  // (losses/sample_weight.h), whose colour, flow and 3D cycle the pipeline
  // skips, and some over it.
  bool sharp_density = false;
};

TestScene MakeCaseScene(const Case& c) {
  TestSceneOptions o;
  o.num_bones = c.num_bones;
  o.delta_skinning = c.delta_skinning;
  o.feature_render_embedding_only = c.feature_render_embedding_only;
  o.hold_cycle_tau = c.hold_cycle_tau;
  TestScene scene = MakeTestScene(o);
  if (c.sharp_density) {
    const SampleWeightSplit split = SharpenDensityUntilSomeSamplesSkip(scene, LossTerm::kRgb);
    EXPECT_GE(split.skipped, 4);
    EXPECT_GE(split.counted, 4);
    scene.batch->Invalidate();
  }
  return scene;
}

class RayGradient : public ::testing::TestWithParam<Case> {};

TEST_P(RayGradient, EqualsRhoPrimeJacobianTransposeResidual) {
  const Case c = GetParam();
  TestScene scene = MakeCaseScene(c);
  RayBatch& batch = *scene.batch;
  ceres::HuberLoss huber(0.1);
  RayRobustLosses robust{};
  if (c.huber) {
    robust[static_cast<int>(LossTerm::kRgb)] = &huber;
    robust[static_cast<int>(LossTerm::kFlow)] = &huber;
    robust[static_cast<int>(LossTerm::kCycle3d)] = &huber;
  }
  Gradient fast, reference;
  const double cost = batch.EvaluateGradient(robust, &fast);
  const double reference_cost = ReferenceGradient(batch, robust, &reference);
  EXPECT_NEAR(cost, reference_cost, 1e-12 * reference_cost);
  ExpectGradientsEqual(fast, reference, *scene.model);
  if (c.num_bones == 0) {
    EXPECT_EQ(fast.count(scene.model->bones()), 0u);
  }

  // Accumulates: a second call adds the same gradient again.
  Gradient twice = fast;
  batch.EvaluateGradient(robust, &twice);
  for (const auto& [block, g] : fast) {
    EXPECT_LE((twice.at(block) - 2.0 * g).cwiseAbs().maxCoeff(), 1e-14 * g.cwiseAbs().maxCoeff());
  }
}

// Ceres' own gradient of the same problem, with some blocks constant: the
// free blocks' gradients (no manifolds here: ambient = tangent) and the cost
// must match.
TEST_P(RayGradient, EqualsCeresProblemEvaluateWithConstantBlocks) {
  const Case c = GetParam();
  TestScene scene = MakeCaseScene(c);
  Model& model = *scene.model;
  RayBatch& batch = *scene.batch;
  ceres::HuberLoss huber(0.1);
  RayRobustLosses robust{};
  if (c.huber) {
    robust[static_cast<int>(LossTerm::kRgb)] = &huber;
    robust[static_cast<int>(LossTerm::kSilhouette)] = &huber;
    robust[static_cast<int>(LossTerm::kCycle2d)] = &huber;
  }
  ceres::Problem::Options po;
  po.evaluation_callback = &batch;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  std::set<double*> all;
  for (int r = 0; r < batch.num_rays(); ++r) {
    for (int t = 0; t < kNumRayTerms; ++t) {
      const LossTerm term = static_cast<LossTerm>(t);
      if (!batch.rays()[r].HasTerm(term, batch.options().weights)) continue;
      std::vector<double*> blocks = batch.TermParameterBlocks(r, term);
      all.insert(blocks.begin(), blocks.end());
      problem.AddResidualBlock(batch.MakeCostFunction(r, term).release(),
                               const_cast<ceres::LossFunction*>(robust[t]), blocks);
    }
  }
  const std::set<double*> constant = {model.color(), model.video(0).intrinsics.data(),
                                      model.frame(0, 1).root_delta.data()};
  std::vector<double*> free;
  for (double* p : all) {
    if (constant.count(p)) {
      problem.SetParameterBlockConstant(p);
    } else {
      free.push_back(p);
    }
  }
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = free;
  eo.num_threads = 1;
  double ceres_cost = 0.0;
  std::vector<double> ceres_gradient;
  ASSERT_TRUE(problem.Evaluate(eo, &ceres_cost, nullptr, &ceres_gradient, nullptr));

  Gradient fast;
  const double cost = batch.EvaluateGradient(robust, &fast);
  EXPECT_NEAR(cost, ceres_cost, 1e-12 * ceres_cost);
  Gradient expected, got;
  size_t offset = 0;
  for (double* p : free) {
    const int size = problem.ParameterBlockSize(p);
    expected[p] = Eigen::Map<const Eigen::VectorXd>(ceres_gradient.data() + offset, size);
    got[p] = fast.at(p);
    offset += size;
  }
  ASSERT_EQ(offset, ceres_gradient.size());
  ExpectGradientsEqual(got, expected, model);
}

INSTANTIATE_TEST_SUITE_P(
    Cases, RayGradient,
    ::testing::Values(Case{"bones_plain", 3, false}, Case{"bones_huber", 3, true},
                      Case{"no_bones_plain", 0, false}, Case{"no_bones_huber", 0, true},
                      Case{"delta_skinning_plain", 3, false, true},
                      Case{"delta_skinning_huber", 3, true, true},
                      Case{"feature_render_embedding_only", 3, true, false, true},
                      Case{"own_cycle_tau", 3, true, true, false, false},
                      Case{"negligible_samples", 3, true, true, false, false, true}),
    [](const ::testing::TestParamInfo<Case>& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace banmo
