#include "banmo/registration/root_init.h"

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <optional>

#include "banmo/registration/root_init_registration.h"
#include "banmo/registration/root_init_smoothing.h"
#include "banmo/registration/root_pose_error.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

// One line on stdout, "<prefix>: ...", unless the prefix is empty.
__attribute__((format(printf, 2, 3))) void Log(const std::string& prefix, const char* format, ...) {
  if (prefix.empty()) return;
  std::printf("%s: ", prefix.c_str());
  std::va_list args;
  va_start(args, format);
  std::vprintf(format, args);
  va_end(args);
}

}  // namespace

void PrepareRootPoseInit(const ModelOptions& options, Dataset* dataset,
                         const std::string& log_prefix) {
  // With ground truth (synthetic data): the initial poses' error, after
  // each step that changes them.
  auto print_pose_error = [&](const char* label) {
    if (const std::optional<RootPoseErrors> e = InitialRootPoseErrors(*dataset)) {
      Log(log_prefix,
          "%s root poses: rotation error %.2f deg mean, %.2f deg p90 against the "
          "ground truth\n",
          label, e->mean_deg, e->p90_deg);
    }
  };
  print_pose_error("initial");
  if (options.root_init_registration.enabled) {
    Timer registration_timer;
    const RootRegistration r = RegisterRootPoseInit(options.root_init_registration, dataset);
    if (!r.registered) {
      Log(log_prefix,
          "root-pose registration (model.root_init_registration): not possible (%s); "
          "initial root poses left as they are\n",
          r.reason.c_str());
    } else {
      Log(log_prefix,
          "root-pose registration (model.root_init_registration): %d frame(s) "
          "registered from %d reference features (%.1f observations per frame), factorisation "
          "%.2f px RMS, bundle adjustment %.2f px median (cost %.4g, depth reversal %.4g; %d "
          "iterations), %.1f s\n",
          r.frames, r.references, r.observations_per_frame, r.affine_rms_px, r.median_residual_px,
          r.cost, r.mirror_cost, r.iterations, registration_timer.Seconds());
      if (r.ambiguous) {
        Log(log_prefix,
            "warning: the registration's depth reversal fits almost as well (cost "
            "ratio %.2f > 0.8): the object may deform too much for a rigid registration\n",
            r.cost / r.mirror_cost);
      }
      for (size_t v = 0; v < r.videos.size(); ++v) {
        const VideoRegistration& c = r.videos[v];
        Log(log_prefix,
            "root-pose registration, video %zu: noise %.2f deg initial, %.2f "
            "registered: %s\n",
            v, c.initial_noise_deg, c.registered_noise_deg,
            c.replaced ? "initial poses replaced" : "initial poses kept");
      }
      if (r.filled > 0) {
        Log(log_prefix, "root-pose registration: %d frame(s) given a neighbour's pose\n", r.filled);
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
        Log(log_prefix,
            "root-pose smoothing (model.root_init_smoothing), video %zu: already "
            "smooth (largest second difference %.2f deg <= acceleration_deg), left as it is\n",
            v, s.max_acceleration_deg);
        continue;
      }
      Log(log_prefix,
          "root-pose smoothing (model.root_init_smoothing), video %zu: noise %.2f "
          "deg estimated, poses turned by %.2f deg mean, %.2f max (%d iterations)\n",
          v, s.noise_deg, s.mean_change_deg, s.max_change_deg, s.iterations);
    }
    print_pose_error("smoothed");
  }
}

}  // namespace banmo
