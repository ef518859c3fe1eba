// `banmo render` as a library call: for chosen frames, one PNG of panels
// side by side and one PNG of error maps, a CSV of per-frame mean errors,
// optionally an MP4 of the panels and a turntable of the canonical mesh
// (docs/render.md).
//
// Files written into OUT (each atomically; the folder is created):
//   frames/video<VV>_frame<TTTTT>.png   5 panels: input RGB | rendered RGB |
//                                       mask agreement | mesh (Lambert) |
//                                       mesh by dominant bone (the mesh panels
//                                       are black when meshes are off or the
//                                       level set is empty)
//   errors/video<VV>_frame<TTTTT>.png   3 panels: rgb | mask | flow error
//   errors.csv                          one row per frame: means and timings
//   sequence.mp4                        the frames/ PNGs in order (optional)
//   turntable/view<NNN>.png             canonical mesh around its y axis (optional)
//   turntable.mp4                       the turntable views (with the MP4 option)
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "banmo/geometry/mesh.h"
#include "banmo/io/dataset.h"
#include "banmo/model/model.h"
#include "banmo/visualize/panels.h"
#include "banmo/visualize/render.h"

namespace banmo {

struct RenderSequenceOptions {
  FrameRenderOptions frame;  // volume rendering of each frame
  // Marching-cubes cells along the longest axis of frame.canonical_bounds
  // for the mesh panels (>= 8), or 0 for no mesh panels.
  int mesh_resolution = 128;
  // Error-map colour scales (> 0): INFERNO from 0 (black) to this value
  // (pale yellow), saturating above.
  double rgb_error_max = 0.25;  // mean |c - c_hat| over channels, colour in [0, 1]
  double mask_error_max = 1.0;  // |o - s_hat|
  double flow_error_max = 2.0;  // endpoint error, pixels of the input image
  // Integer upscale of every panel (>= 1); mesh panels are rasterised at the
  // scaled size, image panels are enlarged (nearest neighbour).
  int scale = 1;
  bool labels = true;  // small text labels on the panels
  // MP4 of the frames/ PNGs in order (OpenCV VideoWriter; see docs/render.md
  // for the codec); fps > 0.
  bool write_video = false;
  double fps = 10.0;
  // Views of the canonical mesh turning about its y axis (0 = none): the
  // first view is the camera of video 0, frame 0, with the mesh centred.
  int turntable_views = 0;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// One rendered frame.
struct FrameReport {
  int video = 0;
  int frame = 0;
  int partner_frame = -1;
  FrameErrors errors;
  double volume_seconds = 0.0;  // RenderFrame (the rendered RGB, mask and flow)
  double total_seconds = 0.0;   // everything for the frame, PNG writing included
};

struct SequenceSummary {
  std::vector<FrameReport> frames;
  int mesh_vertices = 0;      // canonical mesh (0 when meshes are off or empty)
  double mesh_seconds = 0.0;  // canonical mesh and skinning colours
  std::string video_path;     // written MP4, empty if none
  std::string video_note;     // why no MP4 was written, if asked for one
  int turntable_written = 0;
  std::string turntable_video_path;  // turntable.mp4 (with write_video), empty if none
};

// File name stem of a frame: "video<VV>_frame<TTTTT>".
std::string FrameStem(int video, int frame);

// The five panels of a frame as one image (size 5 * W * scale x H * scale):
// observed RGB, rendered RGB, MaskAgreementImage, and the two mesh panels
// (`mesh_in_camera`, `bone_mesh_in_camera`: the articulated mesh in the
// frame's camera coordinates, grey and with dominant-bone vertex colours;
// empty meshes give black panels). `camera` is the frame's camera (model
// intrinsics, image size), unscaled.
cv::Mat FramePanels(const ObservedFrame& observed, const RenderedFrame& rendered,
                    const TriangleMesh& mesh_in_camera, const TriangleMesh& bone_mesh_in_camera,
                    const PinholeCamera& camera, const RenderSequenceOptions& options);

// The three error panels (size 3 * W * scale x H * scale).
cv::Mat ErrorPanels(const ErrorMaps& errors, const RenderSequenceOptions& options);

// Renders `frames` ((video, frame) pairs) of `model` against `dataset` (which
// must match it: CheckDatasetMatchesModel) into out_dir. progress (optional)
// is called after each frame with its report, frames done and total.
SequenceSummary RenderSequence(
    const Model& model, const Dataset& dataset, const std::vector<std::pair<int, int>>& frames,
    const RenderSequenceOptions& options, const std::string& out_dir,
    const std::function<void(const FrameReport&, int done, int total)>& progress = nullptr);

}  // namespace banmo
