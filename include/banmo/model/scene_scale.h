// Scene-scale normalisation (docs/solver.md, "Scene scale"): the solver
// works in model units = dataset units / s, so that the canonical object is
// roughly unit-sized (the initial SDF sphere, the canonical bounds
// [-1.2, 1.2]^3, the bone scales and the near/far planes assume that)
// whatever the units of the data. s is estimated from the data:
//
//   size_f = z_f * |bbox_f| / 2,  z_f = depth of the object centre c in
//            frame f (z of G0^f c, camera coordinates; c = 0, the root
//            origin, unless given), |bbox_f| = diagonal
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

// The estimate above, `centre` in the root frame (dataset units). A frame is
// usable when it is not skipped, has object pixels (kMaskObject) and a
// positive finite depth of the centre.
SceneScaleEstimate EstimateSceneScale(const Dataset& dataset,
                                      const Eigen::Vector3d& centre = Eigen::Vector3d::Zero());

// Where the object is in the root frame (dataset units), from the masks and
// the rough root poses alone: the point nearest, in least squares, to the
// rays through the mask centroids of the usable frames (not skipped, with
// object pixels), each ray weighted 1, plus a prior towards the root origin
// of weight kObjectCentrePrior per frame for directions no pair of rays
// constrains. The centroid of a mask is the projection of the object's
// centre up to perspective and occlusion: a few percent of its size.
// Triangulation needs cameras in different places: when the camera centres
// spread less than kObjectCentreMinBaseline times their mean distance to the
// root origin (identity root poses, as `banmo prepare` writes without
// --poses, put every camera on one spot, where all rays meet), the centre is
// the root origin and `triangulated` is false.
struct ObjectCentreEstimate {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  int frames_used = 0;
  bool triangulated = false;
  double baseline_ratio = 0.0;  // RMS spread of the camera centres / their mean distance
};
constexpr double kObjectCentrePrior = 1e-3;
constexpr double kObjectCentreMinBaseline = 0.1;
ObjectCentreEstimate EstimateObjectCentre(const Dataset& dataset);

// The scene scale s of a model for `dataset`: options.scene_scale if set,
// else EstimateSceneScale(dataset, centre).scale with the object centre when
// options.recentre (else the root origin).
double ResolveSceneScale(const Dataset& dataset, const ModelOptions& options,
                         const Eigen::Vector3d& centre = Eigen::Vector3d::Zero());

}  // namespace banmo
