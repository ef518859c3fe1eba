// The model file: a model written to and read from a folder, so that
// anything that reads a trained model (extract, export, render, resume)
// depends on model/ only. The solver's checkpoints (optim/checkpoint.h) are
// a model folder plus the solver's own files.
//
// Layout of a model folder DIR (format "banmo-model-2"):
//   DIR/model.yaml   format; parameters (number of doubles in params.bin);
//                    scene_scale (the model's s); options (every ModelOptions
//                    field, model/model_options_fields.h, with the model's
//                    current sizes); canonical_bounds {min, max} and
//                    training_sampling {samples_per_ray, near_far_margin,
//                    importance_depth; clip_to_box, clip_margin,
//                    importance_samples, min_sdf_sample when set} when
//                    recorded (Model::
//                    canonical_bounds(), Model::training_sampling()); videos:
//                    per video frames, width, height, intrinsics
//                    [fx, fy, cx, cy]; root_correction: object (G^t =
//                    G0^t dG^t, Model::RootPose).
//   DIR/params.bin   "BANMOPB1", uint64 count, count little-endian doubles in
//                    Model::ForEachBlock order, in model units (root
//                    translations = dataset units / s).
//
// Folders written before the model file existed (model.yaml with format
// "banmo-checkpoint-1": the model options in the `model:` section of the
// solver config text under `config`, the sizes under `model_size`, the
// scene scale 1 when absent) load the same model; their canonical bounds
// were not recorded, and their training sampling is the last stage of that
// config.
//
// Folders without `root_correction` (written before the root correction
// moved to the object side) stored dG_cam with G^t = dG_cam G0^t; they load
// as dG^t = (G0^t)^-1 dG_cam G0^t, the same root poses.
#pragma once

#include <memory>
#include <string>

#include "banmo/model/model.h"

namespace banmo {

// The format written by WriteModelFiles.
inline constexpr char kModelFileFormat[] = "banmo-model-2";
// The format of checkpoints written before the model file existed.
inline constexpr char kLegacyCheckpointFormat[] = "banmo-checkpoint-1";
// The value of model.yaml's root_correction written by WriteModelFiles.
inline constexpr char kRootCorrectionObjectSide[] = "object";

// Writes DIR/params.bin and DIR/model.yaml (each atomically) into the
// existing folder DIR. Throws InputError if a file cannot be written.
void WriteModelFiles(const std::string& dir, const Model& model);

// Reads the model of folder DIR (either format above). Throws InputError
// naming the file and saying what to do on a missing, corrupt or unknown
// file.
std::unique_ptr<Model> ReadModelFiles(const std::string& dir);

// The folder to read for DIR: DIR itself, or DIR.old when DIR has no
// model.yaml but DIR.old has (a save that replaces a folder moves the old one
// to DIR.old first; a crash between its two renames leaves only DIR.old).
std::string ResolveModelFolder(const std::string& dir);

// ReadModelFiles(ResolveModelFolder(dir)).
std::unique_ptr<Model> LoadModel(const std::string& dir);

}  // namespace banmo
