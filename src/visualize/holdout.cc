#include "banmo/visualize/holdout.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "banmo/geometry/se3.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/format.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string JsonNumber(double x) { return std::isfinite(x) ? FormatDouble(x) : "null"; }

}  // namespace

void InterpolateHeldOutFrames(const HoldoutPlan& plan, Model* model) {
  for (const HeldOutFrame& h : plan.frames) {
    const FrameParameters& a = model->frame(h.video, h.before);
    const FrameParameters& b = model->frame(h.video, h.after);
    const Pose root =
        PoseInterpolate(model->RootPose(h.video, h.before), model->RootPose(h.video, h.after), h.w);
    std::vector<double> bones_t(a.bones_t.size());
    for (size_t k = 0; k + kPoseSize <= bones_t.size(); k += kPoseSize) {
      const Pose p = PoseInterpolate(Eigen::Map<const Pose>(a.bones_t.data() + k),
                                     Eigen::Map<const Pose>(b.bones_t.data() + k), h.w);
      std::copy(p.data(), p.data() + kPoseSize, bones_t.begin() + static_cast<long>(k));
    }
    std::vector<double> pose_code(a.pose_code.size());
    for (size_t k = 0; k < pose_code.size(); ++k) {
      pose_code[k] = (1.0 - h.w) * a.pose_code[k] + h.w * b.pose_code[k];
    }
    FrameParameters& f = model->frame(h.video, h.frame);
    // RootPose = root_init * root_delta, so root_delta = root_init^-1 * root.
    Pose init_inverse;
    PoseInverse(f.root_init.data(), init_inverse.data());
    PoseCompose(init_inverse.data(), root.data(), f.root_delta.data());
    f.bones_t = std::move(bones_t);
    f.pose_code = std::move(pose_code);
  }
}

HoldoutScore ScoreHeldOutFrames(
    const Model& model, const Dataset& dataset, const HoldoutPlan& plan,
    const RenderSequenceOptions& options, const std::string& out_dir,
    const std::function<void(const FrameReport&, int done, int total)>& progress) {
  if (plan.frames.empty()) {
    ThrowInputError("--holdout-every ", plan.every, ": no frame is held out (videos too short?)");
  }
  Timer timer;
  std::vector<std::pair<int, int>> frames;
  for (const HeldOutFrame& h : plan.frames) frames.emplace_back(h.video, h.frame);
  HoldoutScore score;
  score.sequence = RenderSequence(model, dataset, frames, options, out_dir, progress);

  std::ostringstream csv;
  csv << "video,frame,before,after,weight,mask_iou,psnr\n";
  double iou_sum = 0.0, psnr_sum = 0.0;
  int iou_count = 0, psnr_count = 0;
  score.mask_iou_min = kNaN;
  for (size_t i = 0; i < plan.frames.size(); ++i) {
    const HeldOutFrame& h = plan.frames[i];
    const FrameErrors& e = score.sequence.frames[i].errors;
    csv << h.video << "," << h.frame << "," << h.before << "," << h.after << ","
        << FormatDouble(h.w) << "," << FormatDouble(e.mask_iou) << "," << FormatDouble(e.psnr)
        << "\n";
    if (std::isfinite(e.mask_iou)) {
      iou_sum += e.mask_iou;
      ++iou_count;
      score.mask_iou_min =
          std::isnan(score.mask_iou_min) ? e.mask_iou : std::min(score.mask_iou_min, e.mask_iou);
    }
    if (std::isfinite(e.psnr)) {
      psnr_sum += e.psnr;
      ++psnr_count;
    }
  }
  score.frames = static_cast<int>(plan.frames.size());
  score.mask_iou = iou_count > 0 ? iou_sum / iou_count : kNaN;
  score.psnr = psnr_count > 0 ? psnr_sum / psnr_count : kNaN;
  WriteFileAtomic(out_dir + "/frames.csv", csv.str());
  std::ostringstream json;
  json << "{\n  \"every\": " << plan.every << ",\n  \"frames\": " << score.frames
       << ",\n  \"mask_iou\": " << JsonNumber(score.mask_iou)
       << ",\n  \"mask_iou_min\": " << JsonNumber(score.mask_iou_min)
       << ",\n  \"psnr\": " << JsonNumber(score.psnr) << "\n}\n";
  WriteFileAtomic(out_dir + "/summary.json", json.str());
  score.seconds = timer.Seconds();
  return score;
}

}  // namespace banmo
