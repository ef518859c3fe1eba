#include "banmo/io/holdout.h"

#include "banmo/geometry/se3.h"
#include "banmo/util/error.h"

namespace banmo {

HoldoutPlan MarkHeldOutFrames(int every, Dataset* dataset) {
  HoldoutPlan plan;
  if (every == 0) return plan;
  if (every < 2) {
    ThrowInputError("--holdout-every: expected 0 (none) or an integer >= 2, got ", every);
  }
  plan.every = every;
  for (int v = 0; v < static_cast<int>(dataset->videos.size()); ++v) {
    std::vector<Frame>& frames = dataset->videos[v].frames;
    const int n = static_cast<int>(frames.size());
    auto chosen = [&](int t) { return t % every == every / 2 && !frames[t].skip; };
    // Usable: neither skipped before nor chosen now.
    auto usable = [&](int t) { return !frames[t].skip && !chosen(t); };
    for (int t = 0; t < n; ++t) {
      if (!chosen(t)) continue;
      int before = -1, after = -1;
      for (int u = t - 1; u >= 0 && before < 0; --u) before = usable(u) ? u : -1;
      for (int u = t + 1; u < n && after < 0; ++u) after = usable(u) ? u : -1;
      if (before < 0 && after < 0) continue;
      HeldOutFrame h;
      h.video = v;
      h.frame = t;
      h.before = before >= 0 ? before : after;
      h.after = after >= 0 ? after : before;
      h.w = h.after == h.before ? 0.0 : static_cast<double>(t - h.before) / (h.after - h.before);
      plan.frames.push_back(h);
    }
  }
  for (const HeldOutFrame& h : plan.frames) {
    std::vector<Frame>& frames = dataset->videos[h.video].frames;
    Frame& f = frames[h.frame];
    f.held_out = true;
    f.skip = true;
    f.root_pose_init =
        PoseInterpolate(frames[h.before].root_pose_init, frames[h.after].root_pose_init, h.w);
  }
  return plan;
}

}  // namespace banmo
