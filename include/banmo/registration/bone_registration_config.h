// Options of the bone motion registration (registration/bone_registration.h;
// docs/solver.md, "Bone registration"): a stage's `bone_registration`
// section (docs/config.md), read with the rest of the solver configuration
// (optim/config.h).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "banmo/util/enum_names.h"
#include "banmo/util/option_check.h"

namespace banmo {

// Where a frame's fit starts (BoneRegistrationConfig::start).
enum class RegistrationStart { kPrevious, kOwn, kLowerCost };

template <>
struct EnumNames<RegistrationStart> {
  static constexpr std::pair<RegistrationStart, const char*> kNames[] = {
      {RegistrationStart::kPrevious, "previous"},
      {RegistrationStart::kOwn, "own"},
      {RegistrationStart::kLowerCost, "lower_cost"}};
};

// The weights of a registration after a stage's last batch (`at` 1.0), where
// they differ from the stage's other registrations: there the shape is
// finished and no later batch moves the fit, so the exact masks may count
// more than the matches (problems/default.yaml). Unset: the registration's
// own weight.
struct BoneRegistrationFinalWeights {
  std::optional<double> match_weight;
  std::optional<double> mask_weight;
  std::optional<double> coverage_weight;
};

// Bone motion registration on feature matches (registration/bone_registration.h;
// docs/solver.md, "Bone registration"): at the given fractions of the stage,
// each frame's bone transforms J_b^t fitted by Levenberg-Marquardt to
// matches between its object pixels' features and a mean-feature embedding
// of the current canonical surface, frame after frame along each video.
struct BoneRegistrationConfig {
  std::vector<double> at;           // fractions of the stage (increasing, in [0, 1]; empty = never)
  int resolution = 128;             // marching-cubes grid of the canonical surface
  int vertices = 3000;              // surface vertices fitted (a random subset)
  int match_pixels = 1000;          // object pixels matched per frame
  double match_weight = 10.0;       // the matches' weight (their mean squared px)
  double huber_px = 2.0;            // Huber scale of a match residual (px)
  double joint_weight = 1.0;        // bones sharing skinning weight move their shared points alike
  double joint_min_weight = 0.15;   // a point joins bones b, c when both weights exceed this
  int joint_points = 40;            // shared points per bone pair at most
  double smooth_weight = 0.01;      // each bone's pull to the previous frame's fit
  double rest_weight = 0.01;        // each bone's pull to the rest pose (the identity)
  double visible_tolerance = 0.05;  // z-buffer tolerance (model units)
  int iterations = 20;              // LM iterations per frame
  double mask_weight = 0.0;         // fitted vertices pulled into the frame's mask (0 = off)
  int mask_points = 1000;           // fitted vertices of the mask term, spread over the proxy
  double coverage_weight = 0.0;     // object pixels pulled to the nearest fitted vertex (0 = off)
  int coverage_pixels = 500;        // object pixels of the coverage term per frame
  int coverage_rounds = 10;         // nearest-vertex ties made this many times (LM solves)
  // Where a frame's fit starts (a video's first frame: its own transforms):
  // the previous frame's fit, the frame's own current transforms, or
  // whichever of the two the terms but the coverage ties cost less.
  RegistrationStart start = RegistrationStart::kPrevious;
  BoneRegistrationFinalWeights after_last_batch;  // a registration at `at` 1.0

  // This config with after_last_batch's weights in place of its own.
  BoneRegistrationConfig AfterLastBatch() const;
  // Its own fields (the rules against the stage: optim/config.cc); `key`
  // its key path, e.g. "stages[2].bone_registration" (util/option_check.h).
  void Check(const OptionChecker& c, const std::string& key) const;
};

}  // namespace banmo
