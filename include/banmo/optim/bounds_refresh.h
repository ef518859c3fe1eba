// The solver's canonical-bounds refresh (ScheduleConfig::bounds_refresh_every)
// with a check against the masks: the box the rays sample may shrink to the
// surface, but not away from the object pixels the data shows.
//
// The refresh takes the box of the largest component of a coarse extraction
// (extract/extract.h, CanonicalBoundsFromSurface). When the model breaks up
// for a while (a registration that does not fit the shape yet, measured on
// the bird at a quarter of the batches: docs/solver.md, "Canonical bounds"),
// that component is a fragment, the box shrinks onto it, the near and far
// planes and the eikonal points follow the box, and the rest of the object
// can never come back: the collapse becomes permanent. The masks say where
// the object is whatever the model does, so a refresh is checked against
// them: the fraction of object pixels whose camera ray meets the box
// (MaskCoverage) may not fall below a floor.
#pragma once

#include <Eigen/Geometry>

#include "banmo/io/dataset.h"
#include "banmo/model/model.h"

namespace banmo {

// Fraction of the object pixels (kMaskObject) of the dataset's usable frames
// whose camera ray meets `box`. The box is in root coordinates (the canonical
// space is the root frame, as for the near and far planes,
// volume/ray_samples.h), each frame's ray through the pixel centre under the
// model's current root pose and intrinsics. Every `stride`-th pixel in x and
// y is counted. Returns 1 when no frame has an object pixel.
double MaskCoverage(const Dataset& dataset, const Model& model, const Eigen::AlignedBox3d& box,
                    int stride = 4);

struct BoundsRefreshResult {
  Eigen::AlignedBox3d box;        // the new bounds
  Eigen::AlignedBox3d surface;    // the surface's box (CanonicalBoundsFromSurface)
  double coverage_current = 1.0;  // MaskCoverage of the bounds before
  double coverage_surface = 1.0;  // of the surface's box
  double coverage = 1.0;          // of the new bounds
  // Where the new bounds lie between the surface's box (0) and the bounds
  // before (1): 0 when the surface's box passes the check.
  double kept = 0.0;
};

// The refreshed bounds: the surface's box when its mask coverage is at least
// 1 - max_coverage_loss, or at least the current bounds' when those meet
// fewer; otherwise the first box on the way from it to the current bounds
// (corners interpolated at 1/4, 1/2, 3/4) that is, or the current bounds
// themselves. max_coverage_loss >= 1 turns the check off (the surface's box
// as it is, without computing the coverages). The current bounds when the
// level set is empty.
BoundsRefreshResult RefreshCanonicalBounds(const Model& model, const Dataset& dataset,
                                           const Eigen::AlignedBox3d& current,
                                           double max_coverage_loss);

}  // namespace banmo
