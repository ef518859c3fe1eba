// Solver checkpoints: the model (a model folder, model/model_file.h) plus
// what the solver needs to resume: the stage and batch, the resolved
// solver config and the solver's state (optimiser moments, RNG state, ...).
// Written atomically: the files go to a fresh folder that then replaces the
// old checkpoint by two renames.
//
// Layout of a checkpoint folder DIR:
//   DIR/model.yaml, DIR/params.bin
//                      the model (model/model_file.h: parameters, sizes,
//                      scene scale, canonical bounds, training sampling)
//   DIR/checkpoint.yaml
//                      format "banmo-checkpoint-3", stage, batch (batches
//                      done in the stage) and config (the resolved solver
//                      config, YAML text)
//   DIR/state.bin      optional solver state (opaque bytes owned by optim/)
// Older checkpoints still load: format "banmo-checkpoint-2" (the same
// checkpoint.yaml with the key `iteration` for `batch`), and those written
// before the model file existed (model.yaml of format "banmo-checkpoint-1"
// holding stage, iteration and config, no checkpoint.yaml).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "banmo/model/model.h"

namespace banmo {

struct CheckpointInfo {
  int stage = 0;       // index of the stage in progress
  int batch = 0;       // batches done in that stage
  std::string config;  // the resolved solver config (YAML text)
};

// The `seed` of the config a checkpoint folder was written with (none when
// that config has no seed): a resumed solve continues its random state.
// Reads checkpoint.yaml only; throws InputError naming the file.
std::optional<uint32_t> ReadCheckpointSeed(const std::string& dir);

// Writes the model (and optional solver state bytes) to DIR atomically.
void SaveCheckpoint(const std::string& dir, const Model& model, const CheckpointInfo& info,
                    const std::string& solver_state = "");

// Loads a checkpoint; throws InputError naming the file on any problem.
std::unique_ptr<Model> LoadCheckpoint(const std::string& dir, CheckpointInfo* info = nullptr,
                                      std::string* solver_state = nullptr);

}  // namespace banmo
