// Options of the registration of root poses from pixel features (config key
// model.root_init_registration; the algorithm is in
// registration/root_init_registration.h, docs/solver.md "Videos without poses").
#pragma once

namespace banmo {

struct RootRegistrationOptions {
  // Whether `banmo solve` registers the frames itself when the initial root
  // poses carry no rotation (every frame's is the same, as `banmo prepare`
  // writes without --poses) and every usable frame has features.
  bool enabled = false;
  // Register even when the initial poses do carry rotations, replacing the
  // rough rotations (their mean stays: the registration is aligned to them).
  bool always = false;
  // How many reference features are tracked across the frames (>= 16): more
  // gives more observations per frame and a larger, slower factorisation.
  int references = 300;
};

}  // namespace banmo
