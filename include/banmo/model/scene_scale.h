// Scene-scale normalisation (docs/solver.md, "Scene scale"): the solver
// works in model units = dataset units / s, so that the canonical object is
// roughly unit-sized (the initial SDF sphere, the canonical bounds
// [-1.2, 1.2]^3, the bone scales and the near/far planes assume that)
// whatever the units of the data. s is estimated from the data:
//
//   size_f = z_f * |bbox_f| / 2,  z_f = root depth of frame f (z of the
//            translation of G0^f, camera coordinates), |bbox_f| = diagonal
//            of the mask's bounding box in focal-length units,
//            sqrt((w / fx)^2 + (h / fy)^2) (w, h in pixels),
//   estimate = 90th percentile of size_f over the frames,
//   s = 2^round(log2(estimate)).
//
// size_f is about the object's half-extent along the image diagonal. Frames
// whose mask touches the image border (a clipped object) are left out unless
// every frame does. s is a power of two, so dividing by it is exact and a
// scene of unit size (s = 1) gives the same bits as without normalisation.
#pragma once

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

struct SceneScaleEstimate {
  double estimate = 1.0;     // the 90th percentile (1 when no frame is usable)
  double scale = 1.0;        // s = 2^round(log2(estimate))
  int frames_used = 0;       // frames in the percentile
  int frames_border = 0;     // usable frames whose mask touches the image border
  bool border_used = false;  // every usable frame touched the border: all were used
};

// The estimate above. A frame is usable when it is not skipped, has object
// pixels (kMaskObject) and a positive finite root depth.
SceneScaleEstimate EstimateSceneScale(const Dataset& dataset);

// options.scene_scale if set, else EstimateSceneScale(dataset).scale.
double ResolveSceneScale(const Dataset& dataset, const ModelOptions& options);

}  // namespace banmo
