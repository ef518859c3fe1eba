#include "banmo/optim/bounds_refresh.h"

#include <glog/logging.h>

#include <algorithm>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/util/parallel.h"
#include "banmo/volume/ray_samples.h"

namespace banmo {

double MaskCoverage(const Dataset& dataset, const Model& model, const Eigen::AlignedBox3d& box,
                    int stride) {
  CHECK_GE(stride, 1);
  CHECK_EQ(static_cast<int>(dataset.videos.size()), model.num_videos());
  struct FrameRef {
    int video, frame;
  };
  std::vector<FrameRef> frames;
  for (int v = 0; v < static_cast<int>(dataset.videos.size()); ++v) {
    for (int t = 0; t < static_cast<int>(dataset.videos[v].frames.size()); ++t) {
      if (!dataset.videos[v].frames[t].skip) frames.push_back({v, t});
    }
  }
  const int n = static_cast<int>(frames.size());
  std::vector<long> object(n, 0), hit(n, 0);
  ParallelFor(n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const cv::Mat& mask = dataset.videos[frames[i].video].frames[frames[i].frame].mask;
      const Pose camera_from_root = model.RootPose(frames[i].video, frames[i].frame);
      const Eigen::Vector4d& k = model.video(frames[i].video).intrinsics;
      for (int y = stride / 2; y < mask.rows; y += stride) {
        const unsigned char* row = mask.ptr<unsigned char>(y);
        for (int x = stride / 2; x < mask.cols; x += stride) {
          if (row[x] != kMaskObject) continue;
          ++object[i];
          // The ray's part in front of the camera, up to 1e3 units (a
          // normalised object is about 2 across): ClipDepthsToBox counts a
          // crossing shorter than 1e-3 of that range as a miss.
          double near = 0.0, far = 1e3;
          hit[i] += ClipDepthsToBox(camera_from_root, box, 0.0, k,
                                    Eigen::Vector2d(x + 0.5, y + 0.5), &near, &far);
        }
      }
    }
  });
  long total_object = 0, total_hit = 0;
  for (int i = 0; i < n; ++i) {
    total_object += object[i];
    total_hit += hit[i];
  }
  return total_object == 0 ? 1.0 : static_cast<double>(total_hit) / total_object;
}

BoundsRefreshResult RefreshCanonicalBounds(const Model& model, const Dataset& dataset,
                                           const Eigen::AlignedBox3d& current,
                                           double max_coverage_loss) {
  CHECK_GE(max_coverage_loss, 0.0);
  BoundsRefreshResult result;
  result.surface = CanonicalBoundsFromSurface(model, current);
  result.box = result.surface;
  if (max_coverage_loss >= 1.0 || result.surface.isApprox(current)) return result;
  result.coverage_current = MaskCoverage(dataset, model, current);
  result.coverage_surface = MaskCoverage(dataset, model, result.surface);
  result.coverage = result.coverage_surface;
  // An absolute floor, not a step from the current box: steps of a few
  // percent each would add up over the refreshes of a solve.
  const double needed = std::min(result.coverage_current, 1.0 - max_coverage_loss);
  if (result.coverage_surface >= needed) return result;
  for (const double s : {0.25, 0.5, 0.75, 1.0}) {
    const Eigen::AlignedBox3d box((1.0 - s) * result.surface.min() + s * current.min(),
                                  (1.0 - s) * result.surface.max() + s * current.max());
    const double coverage = s == 1.0 ? result.coverage_current : MaskCoverage(dataset, model, box);
    if (coverage >= needed || s == 1.0) {
      result.box = box;
      result.coverage = coverage;
      result.kept = s;
      break;
    }
  }
  return result;
}

}  // namespace banmo
