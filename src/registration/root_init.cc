#include "banmo/registration/root_init.h"

#include <algorithm>
#include <optional>

#include "banmo/registration/root_init_registration.h"
#include "banmo/registration/root_init_smoothing.h"
#include "banmo/registration/root_pose_error.h"
#include "banmo/util/format.h"
#include "banmo/util/timer.h"

namespace banmo {

void PrepareRootPoseInit(const ModelOptions& options, Dataset* dataset, LineReporter* reporter) {
  RecordingLineReporter discarded;  // no reporter: the lines go nowhere
  LineReporter& report = reporter != nullptr ? *reporter : discarded;
  // With ground truth (synthetic data): the initial poses' error, after
  // each step that changes them.
  auto print_pose_error = [&](const char* label) {
    if (const std::optional<RootPoseErrors> e = InitialRootPoseErrors(*dataset)) {
      report.Info(
          StrPrintf("%s root poses: rotation error %.2f deg mean, %.2f deg p90 against the "
                    "ground truth (each video aligned on its own: %.2f deg mean)",
                    label, e->mean_deg, e->p90_deg, e->video_aligned_mean_deg));
    }
  };
  print_pose_error("initial");
  if (options.root_init_registration.enabled) {
    Timer registration_timer;
    const RootRegistration r = RegisterRootPoseInit(options.root_init_registration, dataset);
    if (!r.registered) {
      report.Info(
          StrPrintf("root-pose registration (model.root_init_registration): not possible (%s); "
                    "initial root poses left as they are",
                    r.reason.c_str()));
    } else {
      report.Info(StrPrintf(
          "root-pose registration (model.root_init_registration): %d frame(s) "
          "registered from %d reference features (%.1f observations per frame), factorisation "
          "%.2f px RMS, bundle adjustment %.2f px median (cost %.4g, depth reversal %.4g; %d "
          "iterations), %.1f s",
          r.frames, r.references, r.observations_per_frame, r.affine_rms_px, r.median_residual_px,
          r.cost, r.mirror_cost, r.iterations, registration_timer.Seconds()));
      if (r.ambiguous) {
        report.Warning(
            StrPrintf("the registration's depth reversal fits almost as well (cost "
                      "ratio %.2f > 0.8): the object may deform too much for a rigid registration",
                      r.cost / r.mirror_cost));
      }
      for (size_t v = 0; v < r.videos.size(); ++v) {
        const VideoRegistration& c = r.videos[v];
        report.Info(
            StrPrintf("root-pose registration, video %zu: noise %.2f deg initial, %.2f "
                      "registered: %s",
                      v, c.initial_noise_deg, c.registered_noise_deg,
                      c.replaced ? "initial poses replaced" : "initial poses kept"));
      }
      if (r.filled > 0) {
        report.Info(
            StrPrintf("root-pose registration: %d frame(s) given a neighbour's pose", r.filled));
      }
      const bool replaced = std::any_of(r.videos.begin(), r.videos.end(),
                                        [](const VideoRegistration& c) { return c.replaced; });
      if (replaced) print_pose_error("registered");
    }
  }
  if (options.root_init_smoothing.enabled) {
    const std::vector<RootTrackSmoothing> smoothing =
        SmoothRootPoseInit(options.root_init_smoothing, dataset);
    for (size_t v = 0; v < smoothing.size(); ++v) {
      const RootTrackSmoothing& s = smoothing[v];
      if (!s.smoothed) {
        report.Info(StrPrintf(
            "root-pose smoothing (model.root_init_smoothing), video %zu: already "
            "smooth (largest second difference %.2f deg <= acceleration_deg), left as it is",
            v, s.max_acceleration_deg));
        continue;
      }
      report.Info(
          StrPrintf("root-pose smoothing (model.root_init_smoothing), video %zu: noise %.2f "
                    "deg estimated, poses turned by %.2f deg mean, %.2f max (%d iterations)",
                    v, s.noise_deg, s.mean_change_deg, s.max_change_deg, s.iterations));
    }
    print_pose_error("smoothed");
  }
}

}  // namespace banmo
