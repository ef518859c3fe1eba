// The held-out score (`banmo solve --holdout-every N`; docs/solver.md,
// "Held-out frames"): the frames io/holdout.h left out of every loss get
// transforms interpolated from their neighbours and are rendered by the
// training pipeline (visualize/render.h); their mask IoU and PSNR inside
// the mask say how well the model predicts frames it never saw, with or
// without 3D ground truth.
#pragma once

#include <functional>
#include <string>

#include "banmo/io/dataset.h"
#include "banmo/io/holdout.h"
#include "banmo/model/model.h"
#include "banmo/visualize/sequence.h"

namespace banmo {

// Gives each held-out frame of `plan` the transforms interpolated between
// its neighbours' (HeldOutFrame::before / after, weight w): the root pose
// camera_from_root (PoseInterpolate; root_delta set so that
// root_init * root_delta is it), every bone transform (PoseInterpolate per
// bone) and the pose code (linearly).
void InterpolateHeldOutFrames(const HoldoutPlan& plan, Model* model);

struct HoldoutScore {
  int frames = 0;         // held-out frames scored
  double mask_iou = 0.0;  // mean of the frames' mask IoU (NaN: none defined)
  double mask_iou_min = 0.0;
  double psnr = 0.0;     // mean of the frames' PSNR inside the mask, dB
  double seconds = 0.0;  // rendering and writing
  SequenceSummary sequence;
};

// Renders the held-out frames of `plan` (after InterpolateHeldOutFrames)
// into out_dir with RenderSequence (frames/, errors/, errors.csv) and
// writes out_dir/frames.csv (video, frame, neighbours, weight, mask_iou,
// psnr) and out_dir/summary.json (every, frames, mask_iou, mask_iou_min,
// psnr). Throws InputError when the plan holds no frame.
HoldoutScore ScoreHeldOutFrames(
    const Model& model, const Dataset& dataset, const HoldoutPlan& plan,
    const RenderSequenceOptions& options, const std::string& out_dir,
    const std::function<void(const FrameReport&, int done, int total)>& progress = nullptr);

}  // namespace banmo
