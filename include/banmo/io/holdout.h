// Held-out frames (`banmo solve --holdout-every N`; docs/solver.md, "Held-out
// frames"): a score for footage without 3D ground truth. Every N-th frame of
// each video is left out of every loss, and at the end the model renders it
// with root and bone transforms interpolated from its neighbours
// (visualize/holdout.h), to be compared with its mask and colours.
#pragma once

#include <vector>

#include "banmo/io/dataset.h"

namespace banmo {

// One held-out frame and the usable frames its transforms come from: the
// nearest ones before and after it in its video (equal at a video's end),
// with weight w of `after` (frame = (1 - w) before + w after).
struct HeldOutFrame {
  int video = 0;
  int frame = 0;
  int before = 0;
  int after = 0;
  double w = 0.0;
};

struct HoldoutPlan {
  int every = 0;  // 0: no frame held out
  std::vector<HeldOutFrame> frames;
};

// Marks frame t of each video as held out when t % every == every / 2 (so
// frame 0 never is) and the frame is not already skipped: Frame::held_out
// and Frame::skip are set, and its root_pose_init becomes the interpolation
// (PoseInterpolate) of its neighbours' (its own is never read, so a given
// pose cannot inform it). A frame without a usable frame on either side in
// its video is not held out. every == 0 marks nothing; otherwise every must
// be >= 2 (InputError naming --holdout-every).
HoldoutPlan MarkHeldOutFrames(int every, Dataset* dataset);

}  // namespace banmo
