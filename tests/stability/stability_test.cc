// Quick part of the stability suite: each hard case is a short run
// (problems/tiny.yaml's three stages cut to 20 + 4 + 8 batches of 64 rays) on
// a tiny scene rendered in memory, and every batch's losses and every
// parameter must stay finite. The full runs, with their final Chamfer
// distances, are in benchmarks/solver/ (stability.txt, run.sh).
//
// On a failure the message names the case, the stage, the batch and the first
// non-finite loss term or parameter block: that is the minimal reproduction.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "banmo/optim/config.h"
#include "banmo/optim/solver.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"

namespace banmo {
namespace {

struct HardCase {
  std::string name;
  std::string rig = "quadruped";
  double pose_noise_deg = 0;
  synth::PoseNoiseModel pose_noise_model = synth::PoseNoiseModel::kExact;
  std::vector<int> gaps = {1, 2};
  int frames = 6;
  double object_scale = 1;
  int num_bones = 4;
  double init_beta = -1;  // < 0: the config's
  std::string step_rule = "adam";
};

std::ostream& operator<<(std::ostream& os, const HardCase& c) { return os << c.name; }

// Name of the first block with a NaN or Inf ("" if none).
std::string NonFiniteBlock(const Model& model) {
  std::string bad;
  model.ForEachBlock([&](const std::string& name, const double* data, int size) {
    for (int k = 0; k < size && bad.empty(); ++k) {
      if (!std::isfinite(data[k])) bad = name;
    }
  });
  return bad;
}

TEST(StabilityHelpers, NonFiniteBlockNamesTheBlock) {
  ModelOptions options;
  options.num_bones = 2;
  Model model(options, {3}, {PinholeCamera()});
  EXPECT_EQ(NonFiniteBlock(model), "");
  model.frame(0, 1).root_delta[4] = std::nan("");
  EXPECT_EQ(NonFiniteBlock(model), "video0/frame1/root_delta");
}

class StabilityTest : public ::testing::TestWithParam<HardCase> {};

TEST_P(StabilityTest, EveryBatchFinite) {
  const HardCase& c = GetParam();
  synth::SynthOptions o;
  o.num_videos = 2;
  o.frames_per_video = c.frames;
  o.image_size = 48;
  o.flow_gaps = c.gaps;
  o.pose_noise_deg = c.pose_noise_deg;
  o.pose_noise_model = c.pose_noise_model;
  o.object_scale = c.object_scale;
  o.seed = 1;
  const synth::SynthScene scene = synth::RenderSyntheticScene(synth::LoadRig(c.rig), o);

  SolverConfig config = LoadSolverConfig(std::string(BANMO_SOURCE_DIR) + "/problems/tiny.yaml");
  config.model.num_bones = c.num_bones;
  if (c.init_beta > 0) config.model.init_beta = c.init_beta;
  const int iterations[3] = {20, 4, 8};
  ASSERT_EQ(config.stages.size(), 3u);
  for (int s = 0; s < 3; ++s) {
    StageConfig& stage = config.stages[s];
    stage.batches = iterations[s];
    stage.batch_rays = 64;
    stage.step_rule = *ParseEnum<StepRule>(c.step_rule);
    if (stage.step_rule == StepRule::kAlternate) {
      stage.pose_solve.every = 4;  // its per-frame pose blocks move only in pose solves
      stage.pose_solve.rays = 32;
      stage.pose_solve.iterations = 3;
    }
    stage.sampling.flow_gaps = c.gaps;
    stage.log_every = 0;
  }

  Solver solver(scene.dataset, config, MakeModelForDataset(scene.dataset, config.model));
  int batches = 0;
  std::string first_failure;
  TermLosses last_losses;
  SolveOptions options;
  options.quiet = true;
  options.on_batch = [&](const BatchProgress& p, const Model& model) {
    ++batches;
    last_losses = p.losses;
    if (!first_failure.empty()) return;
    std::string what;
    for (const auto& [term, value] : p.losses) {
      if (!std::isfinite(value) && what.empty()) what = "loss " + term;
    }
    const std::string block = NonFiniteBlock(model);
    if (!block.empty()) what += (what.empty() ? "" : ", ") + ("parameter block " + block);
    if (!what.empty()) {
      first_failure = "stage " + std::to_string(p.stage) + " (" + p.stage_name + ") batch " +
                      std::to_string(p.batch) + " (total " + std::to_string(p.total_batches) +
                      "): " + what;
    }
  };
  const SolveResult result = solver.Run(options);
  EXPECT_TRUE(first_failure.empty()) << c.name << ": first non-finite value at " << first_failure;
  EXPECT_EQ(batches, 32);
  for (const StageSummary& s : result.stages) EXPECT_TRUE(s.finite) << s.name;
  std::string losses;
  for (const auto& [term, value] : last_losses) losses += " " + term + "=" + std::to_string(value);
  std::printf("%s: %d batches, last losses:%s\n", c.name.c_str(), batches, losses.c_str());
}

std::vector<HardCase> Cases() {
  std::vector<HardCase> cases;
  auto add = [&](HardCase c) { cases.push_back(c); };
  for (double noise : {20.0, 50.0, 90.0}) {
    HardCase c;
    c.name = "noise" + std::to_string(static_cast<int>(noise));
    c.pose_noise_deg = noise;
    add(c);
  }
  {
    // BANMo's Gaussian noise (mean 90 deg, angles spread from ~0 to 180) with
    // the translation reset to (0, 0, 3).
    HardCase c;
    c.name = "gnoise90";
    c.pose_noise_deg = 90;
    c.pose_noise_model = synth::PoseNoiseModel::kGaussian;
    add(c);
  }
  {
    HardCase c;
    c.name = "noise90_lm";
    c.pose_noise_deg = 90;
    c.step_rule = "lm";
    add(c);
  }
  {
    HardCase c;
    c.name = "bird_25_bones";
    c.rig = "bird";
    c.num_bones = 25;
    add(c);
  }
  {
    HardCase c;
    c.name = "hand_24_bones";
    c.rig = "hand";
    c.num_bones = 24;
    add(c);
  }
  {
    HardCase c;
    c.name = "flow_gap8_only";  // every frame needs a partner 8 frames away: 16 frames
    c.gaps = {8};
    c.frames = 16;
    add(c);
  }
  for (double scale : {0.01, 100.0}) {
    for (const char* rule : {"adam", "lm"}) {
      HardCase c;
      c.name = std::string(scale < 1 ? "scale0.01_" : "scale100_") + rule;
      c.object_scale = scale;
      c.step_rule = rule;
      add(c);
    }
  }
  for (int bones : {1, 64}) {
    HardCase c;
    c.name = "bones" + std::to_string(bones);
    c.num_bones = bones;
    add(c);
  }
  for (double beta : {1e-4, 10.0}) {
    for (const char* rule : {"adam", "alternate"}) {
      HardCase c;
      c.name = std::string(beta < 1 ? "beta1e-4_" : "beta10_") + rule;
      c.init_beta = beta;
      c.step_rule = rule;
      add(c);
    }
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(HardCases, StabilityTest, ::testing::ValuesIn(Cases()),
                         [](const ::testing::TestParamInfo<HardCase>& info) {
                           std::string n = info.param.name;
                           for (char& ch : n) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return n;
                         });

}  // namespace
}  // namespace banmo
