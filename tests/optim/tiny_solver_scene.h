// The tiny synthetic scene and solver config shared by the solver tests: a
// quadruped rendered in memory (2 videos x 6 frames, 48 px) and a small
// model, so a batch takes milliseconds.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "banmo/optim/config.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"

namespace banmo::testing {

// The scene (dataset and ground-truth meshes) for `seed`, every length times
// `object_scale` (SynthOptions::object_scale), rendered once per test program.
inline const synth::SynthScene& TinyQuadrupedScene(uint64_t seed = 1, double object_scale = 1.0) {
  static std::map<std::pair<uint64_t, double>, synth::SynthScene> scenes;
  const std::pair<uint64_t, double> key(seed, object_scale);
  auto it = scenes.find(key);
  if (it == scenes.end()) {
    synth::SynthOptions o;
    o.num_videos = 2;
    o.frames_per_video = 6;
    o.image_size = 48;
    o.flow_gaps = {1, 2};
    o.seed = seed;
    o.object_scale = object_scale;
    it = scenes.emplace(key, synth::RenderSyntheticScene(synth::LoadRig("quadruped"), o)).first;
  }
  return it->second;
}

// The dataset for `seed`, rendered once per test program.
inline const Dataset& TinyQuadrupedDataset(uint64_t seed = 1) {
  return TinyQuadrupedScene(seed).dataset;
}

// One stage of `iterations` batches of 96 rays x 16 samples with the given
// step rule, on a 4-bone model with small MLPs.
inline SolverConfig TinySolverConfig(StepRule step_rule, int iterations) {
  SolverConfig c;
  c.seed = 3;
  c.model.num_bones = 4;
  c.model.field.position_encoding.num_bands = 4;
  c.model.field.sdf_width = 32;
  c.model.field.sdf_layers = 2;
  c.model.field.color_width = 16;
  c.model.field.color_layers = 1;
  c.model.field.embedding_width = 16;
  c.model.field.embedding_layers = 1;
  c.model.field.appearance_code_dim = 2;
  StageConfig s;
  s.name = "tiny";
  s.batches = iterations;
  s.step_rule = step_rule;
  s.batch_rays = 96;
  s.samples_per_ray = 16;
  s.adam.lr = 3e-3;
  s.sampling.flow_gaps = {1, 2};
  s.sampling.eikonal_points = 32;
  s.sampling.match_grid_points = 256;
  s.sampling.match_top_k = 8;
  if (step_rule == StepRule::kAlternate) {
    // Its per-frame pose blocks move only in pose solves: every 3 batches,
    // small ones.
    s.pose_solve.every = 3;
    s.pose_solve.rays = 32;
    s.pose_solve.iterations = 3;
  }
  c.stages.push_back(s);
  return c;
}

// Every parameter of a model, in Model::ForEachBlock order.
inline std::vector<double> AllParameters(Model& m) {
  std::vector<double> out;
  m.ForEachBlock([&](const std::string&, double* d, int n) { out.insert(out.end(), d, d + n); });
  return out;
}

}  // namespace banmo::testing
