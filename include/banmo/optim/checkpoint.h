// Model checkpoints: every parameter block plus the model options, the
// per-frame initial root poses and the solver state needed to resume
// (stage, iteration, optimiser moments, RNG state). Written atomically
// (temp file, fsync, rename).
//
// Layout of a checkpoint folder DIR:
//   DIR/model.yaml     resolved solver config (model options inside), frames per
//                      video, cameras, stage and iteration, scene_scale (the
//                      model's s; a checkpoint without the key loads with 1)
//                      and model_size {num_bones, sdf_width, color_width}: the
//                      model's current sizes, which override the config's
//                      (automatic sizing, optim/auto_size.h, grows them)
//   DIR/params.bin     all parameter blocks, little-endian doubles (see .cc), in
//                      model units (root translations = dataset units / s)
//   DIR/state.bin      optional solver state (opaque bytes owned by optim/)
#pragma once

#include <memory>
#include <string>

#include "banmo/model/model.h"
#include "banmo/optim/config.h"

namespace banmo {

struct CheckpointInfo {
  int stage = 0;       // index of the stage in progress
  int iteration = 0;   // batches done in that stage
  std::string config;  // the resolved solver config (YAML text)
};

// Writes the model (and optional solver state bytes) to DIR atomically.
void SaveCheckpoint(const std::string& dir, const Model& model, const CheckpointInfo& info,
                    const std::string& solver_state = "");

// Loads a checkpoint; throws InputError naming the file on any problem.
std::unique_ptr<Model> LoadCheckpoint(const std::string& dir, CheckpointInfo* info = nullptr,
                                      std::string* solver_state = nullptr);

}  // namespace banmo
