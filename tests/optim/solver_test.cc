// End-to-end tests of the solver on a tiny synthetic scene: the loss
// decreases, every step rule runs and stays finite, a resumed run equals an
// uninterrupted one bit for bit, and retargeting keeps the shared parameters.
#include "banmo/optim/solver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "banmo/deform/bone_joints.h"
#include "banmo/extract/extract.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/retarget.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "tiny_solver_scene.h"

namespace banmo {
namespace {

using testing::AllParameters;

const Dataset& TinyDataset(uint64_t seed = 1) { return testing::TinyQuadrupedDataset(seed); }
SolverConfig TinyConfig(StepRule step_rule, int iterations) {
  return testing::TinySolverConfig(step_rule, iterations);
}

SolveOptions options_quiet() {
  SolveOptions o;
  o.quiet = true;
  return o;
}

double Total(const TermLosses& l) {
  double t = 0;
  for (const auto& [name, v] : l) t += v;
  return t;
}

TEST(Solver, AdamReducesTheLossOnATinyScene) {
  const Dataset& data = TinyDataset();
  const SolverConfig config = TinyConfig(StepRule::kAdam, 80);
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  const SolveResult r = solver.Run(options);
  ASSERT_EQ(r.stages.size(), 1u);
  EXPECT_TRUE(r.stages[0].finite);
  // The silhouette of the initial sphere is far from the quadruped's; 80
  // Adam steps must cut the silhouette loss at least in half (measured ~4x).
  EXPECT_LT(r.stages[0].last_losses.at("silhouette"),
            0.5 * r.stages[0].first_losses.at("silhouette"));
  EXPECT_LT(Total(r.stages[0].last_losses), Total(r.stages[0].first_losses));
}

// The bone-joint regulariser (losses/regularizers.h): with it, neighbouring
// bones' transforms move their joint points alike. Mean gap |J_a m - J_b m|
// over every frame and joint of the final model (joints of its final rest
// bones), the same 40 batches with and without the term. Adam steps a
// coordinate by at most about lr whatever the weight, so the term narrows
// the gaps rather than closing them (measured: 0.036 -> 0.021).
double MeanJointGap(const Model& m) {
  const std::vector<BoneJoint> joints = FindBoneJoints(m.bones(), m.num_bones());
  double sum = 0.0;
  int count = 0;
  for (int v = 0; v < m.num_videos(); ++v) {
    for (const FrameParameters& f : m.video(v).frames) {
      for (const BoneJoint& j : joints) {
        Eigen::Vector3d ya, yb;
        PoseTransformPoint(f.bones_t.data() + kPoseSize * j.a, j.point.data(), ya.data());
        PoseTransformPoint(f.bones_t.data() + kPoseSize * j.b, j.point.data(), yb.data());
        sum += (ya - yb).norm();
        ++count;
      }
    }
  }
  return sum / count;
}

TEST(Solver, BoneJointTermKeepsNeighbouringBonesTogether) {
  const Dataset& data = TinyDataset();
  double gap[2];
  for (const int with : {0, 1}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 40);
    config.stages[0].losses[LossTerm::kBoneJoint].weight = with ? 10.0 : 0.0;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const SolveResult r = solver.Run(options_quiet());
    EXPECT_TRUE(r.stages.at(0).finite);
    gap[with] = MeanJointGap(solver.model());
  }
  EXPECT_GT(gap[0], 0.0);  // the bones do move apart without it
  EXPECT_LT(gap[1], 0.75 * gap[0]) << gap[0] << " -> " << gap[1];
}

// Articulated bone steps (StageConfig::bone_steps_articulated) keep every
// joint's gap |J_a m - J_b m| as it is; the gaps that remain come from the
// rest bones moving under the transforms (the joints move with them). The
// same 40 batches with free steps open them.
TEST(Solver, ArticulatedBoneStepsKeepNeighbouringBonesTogether) {
  const Dataset& data = TinyDataset();
  double gap[2];
  for (const int articulated : {0, 1}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 40);
    config.stages[0].bone_steps_articulated = articulated == 1;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const SolveResult r = solver.Run(options_quiet());
    EXPECT_TRUE(r.stages.at(0).finite);
    gap[articulated] = MeanJointGap(solver.model());
  }
  EXPECT_GT(gap[0], 0.0);
  EXPECT_LT(gap[1], 0.25 * gap[0]) << gap[0] << " -> " << gap[1];
}

// Adam's first step moves each coordinate by lr * scale (the bias-corrected
// m / sqrt(v) is sign(g)), so the group multipliers are visible in one batch:
// log beta moves by exactly lr * beta_lr_scale (up to epsilon / |g|).
TEST(Solver, BetaLearningRateScaleMultipliesTheFirstStep) {
  const Dataset& data = TinyDataset();
  std::vector<double> moved;
  for (const double scale : {1.0, 10.0}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 1);
    config.stages[0].adam.schedule = LrSchedule::kConstant;
    config.stages[0].adam.beta_lr_scale = scale;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const double before = *solver.model().log_beta();
    solver.Run(options_quiet());
    moved.push_back(*solver.model().log_beta() - before);
  }
  const double lr = TinyConfig(StepRule::kAdam, 1).stages[0].adam.lr;
  EXPECT_NEAR(std::abs(moved[0]), lr, 1e-6 * lr);
  EXPECT_NEAR(moved[1], 10.0 * moved[0], 1e-5 * lr);
}

// The same for the intrinsics (pixels), freed from the group list: the first
// step moves fx by lr * intrinsics_lr_scale.
TEST(Solver, IntrinsicsLearningRateScaleMultipliesTheFirstStep) {
  const Dataset& data = TinyDataset();
  std::vector<double> moved;
  for (const double scale : {1.0, 50.0}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 1);
    config.stages[0].constant.clear();
    config.stages[0].adam.schedule = LrSchedule::kConstant;
    config.stages[0].adam.intrinsics_lr_scale = scale;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const double before = solver.model().video(0).intrinsics[0];
    solver.Run(options_quiet());
    moved.push_back(solver.model().video(0).intrinsics[0] - before);
  }
  const double lr = TinyConfig(StepRule::kAdam, 1).stages[0].adam.lr;
  EXPECT_NEAR(std::abs(moved[0]), lr, 1e-6 * lr);
  EXPECT_NEAR(moved[1], 50.0 * moved[0], 5e-5 * lr);
}

// schedule.root_free_from: the root corrections stay exactly where they are
// before the fraction and move after it.
TEST(Solver, RootCorrectionsAreHeldUntilTheirFraction) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 4);
  config.stages[0].schedule.root_free_from = 0.5;  // batches 0 and 1 held
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  const Pose start = solver.model().RootPose(0, 1);
  std::vector<double> moved;
  SolveOptions options = options_quiet();
  options.on_batch = [&](const BatchProgress&, const Model& model) {
    const Pose now = model.RootPose(0, 1);
    double d = 0.0;
    for (int k = 0; k < 7; ++k) d = std::max(d, std::abs(now[k] - start[k]));
    moved.push_back(d);
  };
  solver.Run(options);
  ASSERT_EQ(moved.size(), 4u);
  EXPECT_EQ(moved[0], 0.0);
  EXPECT_EQ(moved[1], 0.0);
  EXPECT_GT(moved[3], 0.0);
}

// schedule.freeze_after_reinit: after the bones are re-initialised (batch 2
// of 8) shape, appearance and root poses stay exactly where they are for
// the freeze (4 batches) while the bone transforms move; then all move.
TEST(Solver, ShapeAndRootAreHeldAfterABoneReinitialisation) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 8);
  config.stages[0].schedule.bone_reinit_at = {0.25};
  config.stages[0].schedule.freeze_after_reinit = 0.5;
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  struct Snapshot {
    std::vector<double> sdf, color, root, bones_t;
  };
  std::vector<Snapshot> after;  // after[i]: the model after batch i's step
  SolveOptions options = options_quiet();
  options.on_batch = [&](const BatchProgress&, const Model& model) {
    Snapshot s;
    s.sdf.assign(model.sdf(), model.sdf() + model.sdf_size());
    s.color.assign(model.color(), model.color() + model.color_size());
    const Pose root = model.RootPose(0, 1);
    s.root.assign(root.data(), root.data() + 7);
    s.bones_t = model.frame(0, 1).bones_t;
    after.push_back(std::move(s));
  };
  solver.Run(options);
  ASSERT_EQ(after.size(), 8u);
  EXPECT_NE(after[1].sdf, after[0].sdf);  // free before the re-initialisation
  for (int i = 2; i <= 5; ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(after[i].sdf, after[1].sdf);
    EXPECT_EQ(after[i].color, after[1].color);
    EXPECT_EQ(after[i].root, after[1].root);
  }
  EXPECT_NE(after[3].bones_t, after[2].bones_t);  // the bones take up the motion
  EXPECT_NE(after[6].sdf, after[5].sdf);          // free again
  EXPECT_NE(after[6].root, after[5].root);
}

// schedule.neus_from: the model renders with VolSDF's density until the
// fraction and with NeuS's from then on.
TEST(Solver, DensitySwitchesToNeusAtItsFraction) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 4);
  config.stages[0].schedule.neus_from = 0.5;  // batches 2 and 3 with NeuS
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  ASSERT_EQ(solver.model().options().density, DensityModel::kVolSdf);
  std::vector<DensityModel> density;
  SolveOptions options = options_quiet();
  options.on_batch = [&](const BatchProgress&, const Model& model) {
    density.push_back(model.options().density);
  };
  solver.Run(options);
  EXPECT_EQ(density, (std::vector<DensityModel>{DensityModel::kVolSdf, DensityModel::kVolSdf,
                                                DensityModel::kNeus, DensityModel::kNeus}));
}

// The temporal step basis with as many cosines as frames is the orthonormal
// DCT-II: a change of coordinates, no loss of freedom. With fewer, a frame's
// squared basis values still sum to about 1 (its step is about lr).
TEST(TemporalBasis, CompleteBasisIsOrthonormalAndTruncatedKeepsTheStepSize) {
  for (const int frames : {1, 6, 24, 30}) {
    for (int i = 0; i < frames; ++i) {
      for (int j = 0; j < frames; ++j) {
        double dot = 0.0;
        for (int t = 0; t < frames; ++t) {
          dot +=
              TemporalBasisValue(i, t, frames, frames) * TemporalBasisValue(j, t, frames, frames);
        }
        EXPECT_NEAR(dot, i == j ? 1.0 : 0.0, 1e-12) << frames << " frames, " << i << ", " << j;
      }
    }
  }
  double mean = 0.0;
  for (int t = 0; t < 24; ++t) {
    for (int k = 0; k < 8; ++k) mean += std::pow(TemporalBasisValue(k, t, 24, 8), 2) / 24;
  }
  EXPECT_NEAR(mean, 1.0, 1e-12);  // 1/K + (K-1)/K: each cosine's mean square is 1/2
}

// adam.bone_basis: one batch of rays from one frame moves every frame of
// that video and none of the other video. With one coefficient (the mean)
// every frame takes the same step, Adam's first step: lr per tangent
// coordinate, so each bone translation moves by exactly lr.
TEST(Solver, BoneBasisStepsEveryFrameOfTheSampledVideo) {
  const Dataset& data = TinyDataset();
  for (const int basis : {0, 1, 6}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 1);
    config.stages[0].adam.schedule = LrSchedule::kConstant;
    config.stages[0].adam.bone_basis = basis;
    config.stages[0].sampling.frames_per_batch = 1;
    // No term reads another frame's bones (flow targets, neighbours).
    config.stages[0].losses[LossTerm::kPoseSmoothness].weight = 0.0;
    config.stages[0].losses[LossTerm::kFlow].weight = 0.0;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const int B = solver.model().num_bones();
    solver.Run(options_quiet());
    const Model& m = solver.model();
    std::vector<int> moved(2, 0);
    int sampled_video = -1;
    for (int v = 0; v < 2; ++v) {
      for (int t = 0; t < 6; ++t) {
        const std::vector<double>& bt = m.frame(v, t).bones_t;
        bool identity = true;
        for (int b = 0; b < B; ++b) {
          identity = identity && bt[kPoseSize * b] == 1.0;
          for (int k = 1; k < kPoseSize; ++k) identity = identity && bt[kPoseSize * b + k] == 0.0;
        }
        if (!identity) {
          ++moved[v];
          sampled_video = v;
        }
      }
    }
    ASSERT_GE(sampled_video, 0) << basis;
    EXPECT_EQ(moved[1 - sampled_video], 0) << basis;
    EXPECT_EQ(moved[sampled_video], basis == 0 ? 1 : 6) << basis;
    if (basis != 1) continue;
    const double lr = config.stages[0].adam.lr;
    const std::vector<double>& first = m.frame(sampled_video, 0).bones_t;
    for (int t = 1; t < 6; ++t) EXPECT_EQ(m.frame(sampled_video, t).bones_t, first) << t;
    for (int b = 0; b < B; ++b) {
      for (int k = 4; k < kPoseSize; ++k) {
        EXPECT_NEAR(std::abs(first[kPoseSize * b + k]), lr, 1e-6 * lr) << b << ", " << k;
      }
    }
  }
}

TEST(Solver, LmAndAlternateStepRulesRunAndStayFinite) {
  const Dataset& data = TinyDataset();
  for (const StepRule rule : {StepRule::kLm, StepRule::kAlternate}) {
    const SolverConfig config = TinyConfig(rule, 6);
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    SolveOptions options;
    options.quiet = true;
    const SolveResult r = solver.Run(options);
    EXPECT_TRUE(r.stages[0].finite) << EnumName(rule);
    EXPECT_LT(Total(r.stages[0].last_losses), 10.0 * Total(r.stages[0].first_losses))
        << EnumName(rule);
  }
}

// The alternate rule: Adam on every block but the per-frame root
// corrections every batch; those move only in the pose solves (every 3
// batches in TinySolverConfig: before batch index 3 of 5). With
// pose_solve.bones the bone transforms too.
TEST(Solver, AlternateMovesRootCorrectionsOnlyInPoseSolves) {
  const Dataset& data = TinyDataset();
  for (const bool bones : {false, true}) {
    SolverConfig config = TinyConfig(StepRule::kAlternate, 5);
    ASSERT_EQ(config.stages[0].pose_solve.every, 3);
    config.stages[0].pose_solve.bones = bones;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const auto blocks = [](const Model& m, bool root) {
      std::vector<double> out;
      for (int v = 0; v < m.num_videos(); ++v) {
        for (const auto& f : m.video(v).frames) {
          if (root) {
            out.insert(out.end(), f.root_delta.data(), f.root_delta.data() + kPoseSize);
          } else {
            out.insert(out.end(), f.bones_t.begin(), f.bones_t.end());
          }
        }
      }
      return out;
    };
    const std::vector<double> root0 = blocks(solver.model(), true);
    const std::vector<double> bones_t0 = blocks(solver.model(), false);
    SolveOptions options;
    options.quiet = true;
    std::vector<std::vector<double>> roots, bones_t;
    options.on_batch = [&](const BatchProgress&, const Model& m) {
      roots.push_back(blocks(m, true));
      bones_t.push_back(blocks(m, false));
    };
    const SolveResult r = solver.Run(options);
    EXPECT_TRUE(r.stages[0].finite) << bones;
    ASSERT_EQ(roots.size(), 5u);
    for (int b = 0; b < 3; ++b) EXPECT_EQ(roots[b], root0) << "batch index " << b;
    EXPECT_NE(roots[3], roots[2]) << bones;  // the pose solve before batch index 3
    EXPECT_EQ(roots[4], roots[3]) << bones;  // and nothing else
    if (bones) {
      EXPECT_EQ(bones_t[2], bones_t0);
      EXPECT_NE(bones_t[3], bones_t[2]);
      EXPECT_EQ(bones_t[4], bones_t[3]);
    } else {
      EXPECT_NE(bones_t[0], bones_t0);  // Adam from the first batch
      EXPECT_NE(bones_t[4], bones_t[3]);
    }
    ASSERT_EQ(r.pose_solves.size(), 1u);
    EXPECT_EQ(r.pose_solves[0].batch, 3);
  }
}

// pose_solve.featureless_only: the solves run on a dataset without pixel
// features and are skipped on one with them.
TEST(Solver, FeaturelessOnlyPoseSolvesRunWithoutFeaturesOnly) {
  Dataset featureless = TinyDataset();
  for (Video& video : featureless.videos) {
    for (Frame& f : video.frames) f.features.release();
  }
  for (const bool features : {true, false}) {
    const Dataset& data = features ? TinyDataset() : featureless;
    SolverConfig config = TinyConfig(StepRule::kAlternate, 4);
    ASSERT_EQ(config.stages[0].pose_solve.every, 3);
    config.stages[0].pose_solve.featureless_only = true;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    SolveOptions options;
    options.quiet = true;
    const SolveResult r = solver.Run(options);
    EXPECT_TRUE(r.stages[0].finite) << features;
    EXPECT_EQ(r.pose_solves.size(), features ? 0u : 1u) << features;
  }
}

TEST(Solver, OnBatchSeesEveryBatchInOrder) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 5);
  config.stages.push_back(config.stages[0]);
  config.stages[1].name = "second";
  config.stages[1].batches = 3;
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  std::vector<BatchProgress> seen;
  options.on_batch = [&](const BatchProgress& p, const Model& model) {
    EXPECT_EQ(&model, &solver.model());
    seen.push_back(p);
  };
  solver.Run(options);
  ASSERT_EQ(seen.size(), 8u);
  for (size_t i = 0; i < seen.size(); ++i) {
    EXPECT_EQ(seen[i].total_batches, static_cast<int>(i) + 1);
    EXPECT_EQ(seen[i].stage, i < 5 ? 0 : 1);
    EXPECT_EQ(seen[i].batch, i < 5 ? static_cast<int>(i) + 1 : static_cast<int>(i) - 4);
    EXPECT_FALSE(seen[i].losses.empty());
    if (i > 0) {
      EXPECT_GE(seen[i].solve_seconds, seen[i - 1].solve_seconds);
    }
  }
  EXPECT_EQ(seen.back().stage_name, "second");
  EXPECT_EQ(seen.back().stage_batches, 3);
}

// sampling.importance_samples: the importance pass adds its samples to the
// stratified ones (ray_samples_test checks the draws); a stage with it runs,
// stays finite, ends elsewhere than with the half-redrawn samples (the rays
// differ) and records the count with the model for banmo render.
TEST(Solver, AddedImportanceSamplesRunAndAreRecordedWithTheModel) {
  const Dataset& data = TinyDataset();
  std::vector<std::vector<double>> ends;
  for (const int added : {0, 16}) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 6);
    config.stages[0].sampling.importance_depth = true;
    config.stages[0].sampling.importance_samples = added;
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    const SolveResult r = solver.Run(options_quiet());
    ASSERT_EQ(r.stages.size(), 1u);
    EXPECT_TRUE(r.stages[0].finite) << added;
    ASSERT_TRUE(solver.model().training_sampling().has_value());
    EXPECT_EQ(solver.model().training_sampling()->importance_samples, added);
    EXPECT_TRUE(solver.model().training_sampling()->importance_depth);
    ends.push_back(AllParameters(solver.model()));
  }
  ASSERT_EQ(ends[0].size(), ends[1].size());
  double max_change = 0.0;
  for (size_t i = 0; i < ends[0].size(); ++i) {
    max_change = std::max(max_change, std::abs(ends[0][i] - ends[1][i]));
  }
  EXPECT_GT(max_change, 1e-6);
}

// Delta skinning switched on at half the stage: before, MLP_Delta and the
// pose codes stay untouched (output layer zero, left out of the batch);
// after, they move and the run stays finite.
TEST(Solver, DeltaSkinningSwitchesOnFromAFraction) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 20);
  config.model.delta_skinning.enabled = true;
  config.model.delta_skinning.width = 8;
  config.model.delta_skinning.pose_code_dim = 4;
  config.stages[0].schedule.delta_skinning_from = 0.5;
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  const std::vector<double> code0 = solver.model().frame(0, 0).pose_code;
  const std::vector<double> delta0(
      solver.model().delta_skinning_params(),
      solver.model().delta_skinning_params() + solver.model().delta_skinning_size());
  SolveOptions options;
  options.quiet = true;
  bool zero_before = true, nonzero_after = false;
  options.on_batch = [&](const BatchProgress& p, const Model& model) {
    if (p.batch <= 10) zero_before = zero_before && !model.DeltaSkinningIsNonZero();
    if (p.batch == 20) nonzero_after = model.DeltaSkinningIsNonZero();
    if (p.batch == 10) {
      EXPECT_TRUE(std::equal(delta0.begin(), delta0.end(), model.delta_skinning_params()));
    }
  };
  const SolveResult r = solver.Run(options);
  EXPECT_TRUE(r.stages[0].finite);
  EXPECT_TRUE(zero_before);
  EXPECT_TRUE(nonzero_after);
  bool codes_moved = false;
  for (int t = 0; t < 6; ++t) {
    codes_moved = codes_moved || solver.model().frame(0, t).pose_code != code0;
  }
  EXPECT_TRUE(codes_moved);

  // The other step rules with delta skinning on from the start (LM uses the
  // full per-row Jacobians, including the 3D cycle's MLP_Delta rows).
  for (const StepRule rule : {StepRule::kLm, StepRule::kAlternate}) {
    SolverConfig c = TinyConfig(rule, 4);
    c.model.delta_skinning = config.model.delta_skinning;
    c.stages[0].schedule.delta_skinning_from = 0.0;
    c.stages[0].losses[LossTerm::kCycle3d].weight = 1.0;
    Solver s2(data, c, MakeModelForDataset(data, c.model));
    const SolveResult r2 = s2.Run(options_quiet());
    EXPECT_TRUE(r2.stages[0].finite) << EnumName(rule);
    EXPECT_TRUE(s2.model().DeltaSkinningIsNonZero()) << EnumName(rule);
  }
}

// Runs `config` straight and as interrupted pieces (stopping after each
// total batch count in `stops`, then resuming); the final parameters must
// be the same bit for bit.
void ExpectResumeEqualsStraight(const SolverConfig& config, const std::vector<int>& stops,
                                const std::string& name) {
  const Dataset& data = TinyDataset();
  const std::string root = ::testing::TempDir() + "/" + name;
  std::filesystem::remove_all(root);
  SolveOptions options;
  options.quiet = true;
  options.out_dir = root + "/straight";
  Solver straight(data, config, MakeModelForDataset(data, config.model));
  ASSERT_FALSE(straight.Run(options).interrupted);

  options.out_dir = root + "/resumed";
  for (size_t i = 0; i <= stops.size(); ++i) {
    options.stop_after_batches = i < stops.size() ? stops[i] : -1;
    options.resume = i > 0;
    Solver piece(data, config, MakeModelForDataset(data, config.model));
    ASSERT_EQ(piece.Run(options).interrupted, i < stops.size()) << "piece " << i;
    if (i == stops.size()) {
      const std::vector<double> a = AllParameters(straight.model());
      const std::vector<double> b = AllParameters(piece.model());
      ASSERT_EQ(a.size(), b.size());
      EXPECT_EQ(0, std::memcmp(a.data(), b.data(), sizeof(double) * a.size()))
          << "resumed parameters differ from the uninterrupted run";
    }
  }
}

TEST(Solver, ResumeGivesTheSameResultAsAnUninterruptedRun) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 5);
  StageConfig lm = config.stages[0];
  lm.name = "lm";
  lm.step_rule = StepRule::kLm;
  lm.batches = 3;
  lm.sampling.active_fraction = 0.25;
  config.stages.push_back(lm);
  ExpectResumeEqualsStraight(config, {6}, "banmo_resume_test");  // stops inside the second stage
}

// The solver's messages go to SolveOptions::reporter: the stage's start and
// end, a progress line every log_every batches and at the last, the
// schedules' events; with quiet, none of these.
TEST(Solver, ReportsThroughTheReporter) {
  const Dataset& data = TinyDataset();
  SolverConfig config = TinyConfig(StepRule::kAdam, 20);
  config.stages[0].log_every = 10;
  config.stages[0].schedule.neus_from = 0.5;
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  RecordingReporter reporter;
  SolveOptions options;
  options.reporter = &reporter;
  solver.Run(options);
  std::vector<std::pair<SolveMessageKind, int>> said;
  for (const SolveMessage& m : reporter.messages) {
    EXPECT_EQ(m.stage, config.stages[0].name);
    EXPECT_EQ(m.text.find('\n'), std::string::npos) << m.text;
    said.emplace_back(m.kind, m.batch);
  }
  using K = SolveMessageKind;
  const std::vector<std::pair<SolveMessageKind, int>> expected = {{K::kStage, 0},  {K::kBatch, 1},
                                                                  {K::kEvent, 10}, {K::kBatch, 11},
                                                                  {K::kBatch, 20}, {K::kStage, 20}};
  EXPECT_EQ(said, expected);
  EXPECT_EQ(reporter.messages[2].text, "density: NeuS from batch 10 on");
  // The stage's end line gives the density's scale it ended with.
  const double beta = std::exp(*solver.model().log_beta());
  EXPECT_NE(reporter.messages.back().text.find(StrPrintf(", beta %.4g", beta)), std::string::npos)
      << reporter.messages.back().text;
  EXPECT_EQ(reporter.messages[1].text.rfind("    1/20 ", 0), 0u) << reporter.messages[1].text;
  EXPECT_NE(reporter.messages[1].text.find(" | total="), std::string::npos);

  RecordingReporter quiet;
  options.reporter = &quiet;
  options.quiet = true;
  Solver again(data, config, MakeModelForDataset(data, config.model));
  again.Run(options);
  EXPECT_TRUE(quiet.messages.empty());
}

TEST(Solver, RetargetingFitsPosesAndKeepsSharedParameters) {
  const Dataset& data = TinyDataset();
  const SolverConfig config = TinyConfig(StepRule::kAdam, 10);
  Solver trained(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  trained.Run(options);

  const Dataset& other = TinyDataset(7);
  std::unique_ptr<Model> model = MakeModelForDataset(other, config.model);
  ApplyRetarget(trained.model(), "trained", model.get(), &options);  // optim/retarget.h
  const std::vector<double> sdf(model->sdf(), model->sdf() + model->sdf_size());
  const Pose root_before = model->frame(0, 0).root_delta;
  Solver retarget(other, config, std::move(model));
  const SolveResult r = retarget.Run(options);
  EXPECT_TRUE(r.stages[0].finite);
  EXPECT_EQ(0, std::memcmp(sdf.data(), retarget.model().sdf(), sizeof(double) * sdf.size()));
  EXPECT_NE(retarget.model().frame(0, 0).root_delta, root_before);
}

// The temporal bases' Adam moments are solver state: a resumed run with
// both bases (stopped between, and across a bone re-initialisation, which
// drops the bones' moments) equals the uninterrupted one.
TEST(Solver, ResumeWithTemporalBasesIsBitwiseIdentical) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 6);
  config.stages[0].adam.bone_basis = 3;
  config.stages[0].adam.root_basis = 2;
  config.stages[0].schedule.bone_reinit_at = {0.5};
  ExpectResumeEqualsStraight(config, {2, 4}, "banmo_resume_basis_test");
}

// Articulated bone steps rebuild their joint tree from the rest bones at
// every batch and change the bone transforms' tangent size between stages
// (their Adam moments start again): a run of articulated Adam (across a
// bone re-initialisation), free Adam and articulated LM stopped in each
// stage resumes to the uninterrupted result.
TEST(Solver, ResumeWithArticulatedBoneStepsIsBitwiseIdentical) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 6);
  config.stages[0].bone_steps_articulated = true;
  config.stages[0].schedule.bone_reinit_at = {0.5};
  StageConfig free = config.stages[0];
  free.name = "free";
  free.batches = 3;
  free.bone_steps_articulated = false;
  free.schedule.bone_reinit_at = {};
  StageConfig lm = free;
  lm.name = "lm";
  lm.batches = 2;
  lm.step_rule = StepRule::kLm;
  lm.bone_steps_articulated = true;
  config.stages.push_back(free);
  config.stages.push_back(lm);
  ExpectResumeEqualsStraight(config, {2, 4, 7, 10}, "banmo_resume_articulated_test");
}

// A checkpoint written exactly at a bone re-initialisation batch (before the
// batch's schedules run) resumes into that re-initialisation.
TEST(Solver, ResumeAtABoneReinitBatchReinitializes) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 6);
  config.stages[0].schedule.bone_reinit_at = {0.5};  // batch 3
  ExpectResumeEqualsStraight(config, {3}, "banmo_resume_reinit_test");
}

// The density switch and the freeze after a re-initialisation depend only
// on the batch (and the model file records the density): runs stopped at
// the switch, inside the freeze and after both resume to the uninterrupted
// result.
TEST(Solver, ResumeAcrossTheDensitySwitchAndAFreezeIsBitwiseIdentical) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 8);
  config.stages[0].schedule.bone_reinit_at = {0.25};      // batch 2
  config.stages[0].schedule.freeze_after_reinit = 0.375;  // batches 2-4
  config.stages[0].schedule.neus_from = 0.5;              // batch 4 on
  ExpectResumeEqualsStraight(config, {3, 4, 6}, "banmo_resume_neus_freeze_test");
}

// The alternate rule with periodic pose solves (every 3 batches, bone
// transforms included): stopped at a solve's batch, between solves and
// after the second, it resumes to the uninterrupted result.
TEST(Solver, ResumeWithAlternateIsBitwiseIdentical) {
  SolverConfig config = TinyConfig(StepRule::kAlternate, 7);
  config.stages[0].pose_solve.bones = true;
  ExpectResumeEqualsStraight(config, {3, 5, 6}, "banmo_resume_alternate_test");
}

// Pose solves (with the search) draw from the run's RNG and drop the root
// Adam moments: a run stopped at their batch and one stopped after them both
// resume to the uninterrupted result. The solves also report every frame.
TEST(Solver, ResumeWithPoseSolvesIsBitwiseIdentical) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 6);
  config.stages[0].pose_solve.at = {0.5};  // batch 3
  config.stages[0].pose_solve.rays = 32;
  config.stages[0].pose_solve.iterations = 2;
  config.stages[0].pose_solve.search_ratio = 1.0;  // about half the frames search
  config.stages[0].pose_solve.search_rotations = 4;
  config.stages[0].pose_solve.search_keep = 1;
  ExpectResumeEqualsStraight(config, {3, 4}, "banmo_resume_pose_solve_test");

  const Dataset& data = TinyDataset();
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  SolveOptions options;
  options.quiet = true;
  const SolveResult r = solver.Run(options);
  ASSERT_EQ(r.pose_solves.size(), 1u);
  const PoseSolveReport& report = r.pose_solves[0];
  EXPECT_EQ(report.batch, 3);
  EXPECT_EQ(static_cast<int>(report.frames.size()), data.NumFrames() - data.NumSkippedFrames());
  EXPECT_GT(report.searched, 0);
  for (const FramePoseSolve& f : report.frames) {
    EXPECT_LE(f.cost_after, f.cost_before) << f.video << "/" << f.frame;
    EXPECT_TRUE(std::isfinite(f.rotation_deg));
  }
}

// A registration small enough for the tiny scene, at fractions `at`.
BoneRegistrationConfig TinyRegistration(std::vector<double> at) {
  BoneRegistrationConfig reg;
  reg.at = std::move(at);
  reg.resolution = 32;
  reg.vertices = 300;
  reg.match_pixels = 100;
  reg.iterations = 3;
  return reg;
}

// A bone registration right after a re-initialisation (batch 3 of 6) sets
// every frame's bone transforms away from the identity, draws from the
// run's RNG and drops the bone transforms' Adam moments: runs stopped at its
// batch and after it resume to the uninterrupted result.
TEST(Solver, BoneRegistrationAfterAReinitialisationMovesTheBonesAndResumes) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 6);
  config.stages[0].schedule.bone_reinit_at = {0.5};
  config.stages[0].bone_registration = TinyRegistration({0.5});
  ExpectResumeEqualsStraight(config, {3, 4}, "banmo_resume_bone_registration_test");

  const Dataset& data = TinyDataset();
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  std::vector<std::vector<double>> bones_t;  // frame (0, 2) after each batch
  SolveOptions options = options_quiet();
  options.on_batch = [&](const BatchProgress&, const Model& model) {
    bones_t.push_back(model.frame(0, 2).bones_t);
  };
  solver.Run(options);
  ASSERT_EQ(bones_t.size(), 6u);
  // After batch 3 (re-initialised to the identity, registered, one step):
  // the registration turned some bone by more than one Adam step could.
  double largest = 0.0;
  for (size_t b = 0; b < bones_t[3].size() / kPoseSize; ++b) {
    const double w = std::min(1.0, std::abs(bones_t[3][kPoseSize * b]));
    largest = std::max(largest, 2.0 * std::acos(w));
  }
  EXPECT_GT(largest, 0.02) << "rad";
}

// `at` 1.0 registers after the stage's last batch: the bones the solve
// returns differ from those of its last step, and a run stopped at the
// stage's end and resumed (the next stage's checkpoint) matches a straight
// run, so the registration runs once and is saved.
TEST(Solver, BoneRegistrationAtTheStagesEndRunsAfterItsLastBatch) {
  SolverConfig config = TinyConfig(StepRule::kAdam, 4);
  config.stages[0].bone_registration = TinyRegistration({1.0});
  StageConfig second = config.stages[0];
  second.name = "second";
  second.batches = 2;
  second.bone_registration.at.clear();
  config.stages.push_back(second);
  ExpectResumeEqualsStraight(config, {4, 5}, "banmo_resume_end_registration_test");

  config.stages.pop_back();
  const Dataset& data = TinyDataset();
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  std::vector<double> last_step;
  SolveOptions options = options_quiet();
  options.on_batch = [&](const BatchProgress&, const Model& model) {
    last_step = model.frame(0, 2).bones_t;
  };
  solver.Run(options);
  const std::vector<double>& registered = solver.model().frame(0, 2).bones_t;
  ASSERT_EQ(registered.size(), last_step.size());
  double moved = 0.0;
  for (size_t i = 0; i < registered.size(); ++i) {
    moved = std::max(moved, std::abs(registered[i] - last_step[i]));
  }
  EXPECT_GT(moved, 1e-3) << "no registration after the last batch";
}

// bone_registration.after_last_batch weighs only the registration after the
// stage's last batch: with it set, the registration at the middle of the
// stage (and every batch) is bit for bit the same, the last one is not.
TEST(Solver, AfterLastBatchWeightsChangeOnlyTheLastRegistration) {
  auto run = [](bool override_last) {
    SolverConfig config = TinyConfig(StepRule::kAdam, 4);
    config.stages[0].bone_registration = TinyRegistration({0.5, 1.0});
    if (override_last) {
      config.stages[0].bone_registration.after_last_batch.match_weight = 0.5;
      config.stages[0].bone_registration.after_last_batch.mask_weight = 50.0;
    }
    const Dataset& data = TinyDataset();
    Solver solver(data, config, MakeModelForDataset(data, config.model));
    std::vector<std::vector<double>> steps;
    SolveOptions options = options_quiet();
    options.on_batch = [&](const BatchProgress&, const Model& model) {
      steps.push_back(model.frame(0, 2).bones_t);
    };
    solver.Run(options);
    steps.push_back(solver.model().frame(0, 2).bones_t);
    return steps;
  };
  const std::vector<std::vector<double>> plain = run(false), last = run(true);
  ASSERT_EQ(plain.size(), 5u);
  ASSERT_EQ(last.size(), 5u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(plain[i], last[i]) << "batch " << i;
  double moved = 0.0;
  for (size_t i = 0; i < plain[4].size(); ++i) {
    moved = std::max(moved, std::abs(plain[4][i] - last[4][i]));
  }
  EXPECT_GT(moved, 1e-4) << "the last registration ignored after_last_batch";
}

SolverConfig AutoSizeConfig(int iterations) {
  SolverConfig config = TinyConfig(StepRule::kAdam, iterations);
  config.model.auto_size.enabled = true;
  config.model.auto_size.grow_at = {0.3, 0.6};
  config.model.auto_size.error_ratio = 1.0;  // some bone is always at or above the mean
  config.model.auto_size.max_bones = 6;
  config.model.auto_size.max_width = 64;
  config.model.auto_size.eval_rays = 192;
  return config;
}

// A tiny solve with automatic sizing: bones split at the first grow point
// (up to max_bones), the MLPs widen at the second, the run stays finite and
// the model has a surface.
TEST(Solver, AutoSizeGrowsBonesThenWidthsInATinySolve) {
  const Dataset& data = TinyDataset();
  const SolverConfig config = AutoSizeConfig(20);
  Solver solver(data, config, MakeModelForDataset(data, config.model));
  const SolveResult r = solver.Run(options_quiet());
  ASSERT_EQ(r.auto_size.size(), 2u);
  EXPECT_EQ(r.auto_size[0].batch, 6);
  EXPECT_EQ(r.auto_size[1].batch, 12);
  EXPECT_GT(r.auto_size[0].bones_after, 4);
  EXPECT_EQ(r.auto_size[0].sdf_width_after, 32);
  const Model& m = solver.model();
  EXPECT_EQ(m.num_bones(), r.auto_size[0].bones_after);
  if (r.auto_size[0].bones_after == 6) {  // at max_bones: the second step widens
    EXPECT_TRUE(r.auto_size[1].splits.empty());
    EXPECT_EQ(m.options().field.sdf_width, 64);
    EXPECT_EQ(m.options().field.color_width, 32);
  }
  EXPECT_EQ(m.sdf_size(), m.field().SdfParameterSize());
  EXPECT_TRUE(r.stages[0].finite);
  ExtractOptions extract;
  extract.grid.resolution = 32;
  extract.grid.bounds_min = solver.canonical_bounds().min();
  extract.grid.bounds_max = solver.canonical_bounds().max();
  EXPECT_GT(ExtractCanonicalMesh(m, extract).NumVertices(), 0);
}

// Resume across grow steps: interrupted exactly at the first grow batch
// (the checkpoint precedes the grow), then after both (the checkpoint holds
// the grown sizes and the remapped Adam moments): bitwise the straight run.
TEST(Solver, ResumeAcrossAutoSizeGrowthIsBitwiseIdentical) {
  SolverConfig config = AutoSizeConfig(10);  // grow at batches 3 and 6
  StageConfig second = config.stages[0];
  second.name = "second";
  second.batches = 2;
  config.stages.push_back(second);
  ExpectResumeEqualsStraight(config, {3, 7}, "banmo_resume_autosize_test");
  // The checkpoint of the finished run has the grown sizes.
  const std::unique_ptr<Model> model =
      LoadCheckpoint(::testing::TempDir() + "/banmo_resume_autosize_test/resumed/checkpoint");
  EXPECT_GT(model->num_bones(), 4);
}

TEST(Checkpoint, RoundTripAndErrors) {
  const Dataset& data = TinyDataset();
  const SolverConfig config = TinyConfig(StepRule::kAdam, 1);
  std::unique_ptr<Model> model = MakeModelForDataset(data, config.model);
  model->sdf()[3] = 0.125;
  const std::string dir = ::testing::TempDir() + "/banmo_checkpoint_test";
  std::filesystem::remove_all(dir);
  SaveCheckpoint(dir, *model, CheckpointInfo{1, 7, SolverConfigToYaml(config)}, "state");
  CheckpointInfo info;
  std::string state;
  std::unique_ptr<Model> back = LoadCheckpoint(dir, &info, &state);
  EXPECT_EQ(info.stage, 1);
  EXPECT_EQ(info.batch, 7);
  EXPECT_EQ(state, "state");
  EXPECT_EQ(AllParameters(*model), AllParameters(*back));
  // A truncated parameter file is an error naming it.
  std::filesystem::resize_file(dir + "/params.bin", 100);
  try {
    LoadCheckpoint(dir);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("params.bin"), std::string::npos) << e.what();
  }
  EXPECT_THROW(LoadCheckpoint(dir + "/nonexistent"), InputError);
}

}  // namespace
}  // namespace banmo
