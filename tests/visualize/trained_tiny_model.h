// A tiny model trained on the solver tests' in-memory quadruped scene
// (tests/optim/tiny_solver_scene.h), once per test program, for the render
// tests: the rendered pictures must agree with the data where the model is
// good, and an untrained model must not.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>

#include "../optim/tiny_solver_scene.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/optim/solver.h"
#include "banmo/util/error.h"

namespace banmo::testing {

// Batches of the training run (measured: 8-14 s on 2 cores shared with
// other jobs).
inline constexpr int kTinyTrainingBatches = 200;

// The solver config of the trained model: the solver tests' tiny config with
// 10 % of the rays inside the mask instead of 50 %. Full-image pictures are
// judged here, and with the object ~10 % of the image a foreground-heavy
// draw trains a model that over-covers the background (measured mean mask
// IoU 0.48 with 50 %, 0.58 with 10 %, for the same 200 batches).
inline const SolverConfig& TinyRenderConfig() {
  static const SolverConfig config = [] {
    SolverConfig c = TinySolverConfig(StepRule::kAdam, kTinyTrainingBatches);
    c.stages[0].sampling.foreground_fraction = 0.1;
    return c;
  }();
  return config;
}

// A fresh, untrained model for the tiny dataset (MLPs at their sphere init).
inline std::unique_ptr<Model> UntrainedTinyModel() {
  return MakeModelForDataset(TinyQuadrupedDataset(), TinyRenderConfig().model);
}

// The trained model (trained on first use). ctest runs every test case in
// its own process, so the first one keeps the model as a checkpoint in the
// temp folder, keyed by this test program's modification time (a rebuild
// retrains), and later processes load it (bit-identical parameters).
inline const Model& TrainedTinyModel() {
  static std::unique_ptr<Model> model = [] {
    namespace fs = std::filesystem;
    std::error_code ec;
    const auto stamp = fs::last_write_time("/proc/self/exe", ec).time_since_epoch().count();
    const fs::path cache = fs::temp_directory_path() /
                           ("banmo_visualize_tiny_model_" + std::to_string(ec ? 0 : stamp));
    if (!ec && fs::exists(cache / "params.bin")) {
      try {
        return LoadCheckpoint(cache.string());
      } catch (const InputError&) {  // another process is writing it: train
      }
    }
    Solver solver(TinyQuadrupedDataset(), TinyRenderConfig(), UntrainedTinyModel());
    SolveOptions options;
    options.quiet = true;
    options.out_dir = cache.string() + ".solve." + std::to_string(::getpid());
    solver.Run(options);
    // The solver wrote out_dir/checkpoint: rename it into place (atomic; if
    // another process got there first, keep theirs and load ours).
    const std::string written = options.out_dir + "/checkpoint";
    std::error_code rename_error;
    fs::rename(written, cache, rename_error);
    std::unique_ptr<Model> trained = LoadCheckpoint(rename_error ? written : cache.string());
    fs::remove_all(options.out_dir, ec);
    return trained;
  }();
  return *model;
}

}  // namespace banmo::testing
