// Meshes from a BANMo model (docs/extract.md
// "Extraction"): the canonical surface (zero level set of the SDF MLP) by
// marching cubes, its vertex colours, articulated per-frame meshes in each
// frame's camera coordinates, and bones and skinning weights for inspection.
//
// Frames: the canonical (rest) space X*; a frame's root space (after the
// forward warp with rest bones, bones.h); the camera of frame t of video v,
//   x_in_camera = G^t * ForwardWarp(J^t, X*),  G^t = model.RootPose(v, t)
// (camera_from_root, OpenCV axes), which is what `banmo eval` expects.
//
// Units: the functions below work in the model's units (model.h: dataset
// units / model.scene_scale()), as do ExtractOptions::grid's bounds; the
// files WriteExtraction writes are in dataset units (MeshInDatasetUnits).
//
// Files written by WriteExtraction into OUT (docs/extract.md):
//   canonical.ply              canonical mesh with vertex colours
//   frames/video<VV>_frame<TTTTT>.ply
//                              articulated mesh of frame T of video V in that
//                              frame's camera coordinates, zero-padded so a
//                              name sort is video-major, frame order
//                              (`banmo eval --pred OUT/frames`)
//   bones.ply                  one ellipsoid per rest bone (B > 0)
//   skinning.ply               canonical mesh coloured by dominant bone (B > 0)
//   skinning_weights.npy       float32 array (V, B): row i = skinning weights
//                              of vertex i of canonical.ply (B > 0)
//   embedding.npy              float32 array (V, 16): row i = canonical
//                              embedding psi of vertex i (raw MLP output)
//   extract.json               options, counts and timings (bounds in dataset
//                              units, scene_scale)
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "banmo/extract/marching_cubes.h"
#include "banmo/geometry/mesh.h"
#include "banmo/model/model.h"

namespace banmo {

// Which frames get an articulated mesh.
struct FrameSelection {
  // All frames of all videos (then `frames` is ignored).
  bool all = true;
  // (video, frame) pairs, in the order given.
  std::vector<std::pair<int, int>> frames;
};

// Parses "all", "none", or a comma-separated list of items "V:T" (frame T of
// video V), "V:T0-T1" (inclusive range) or "V:*" (every frame of video V).
// Indices are checked against the model. Throws InputError naming `flag`.
FrameSelection ParseFrameSelection(const std::string& text, const Model& model,
                                   const std::string& flag = "--frames");

// Default of ExtractOptions::min_component_fraction: the parts of the
// trained models measured that the zero level set separates from the body
// (a wing, legs) are 0.2-14 % of the largest component's faces, and keeping
// every component above 0.1 % scored better on the Fox than 1 % or the
// largest alone; what it drops are specks of a few faces (benchmarks/log/2026-11.md,
// "Stage 3 and detached parts").
inline constexpr double kDefaultMinComponentFraction = 0.001;

struct ExtractOptions {
  // Grid, level, capping at the bounds and batch size of the SDF sampling.
  // resolution: 256 for final meshes, 64-128 for quick looks.
  GridOptions grid = [] {
    GridOptions g;
    g.resolution = 256;
    return g;
  }();
  // Connected components kept: those with at least this fraction of the
  // largest one's faces ([0, 1]; 0 keeps every component, 1 only the
  // largest). Drops floaters but keeps parts the zero level set separates
  // from the body at this resolution, such as thin legs or a wing
  // (kDefaultMinComponentFraction, docs/extract.md "Components").
  double min_component_fraction = kDefaultMinComponentFraction;
  // Appearance code used for the vertex colours: that video's code, or the
  // zero code when -1 or when the model has no such video (>= -1). Colours
  // use the view direction (0, 0, 1) in canonical coordinates.
  int color_video = 0;
  // Frames written by WriteExtraction.
  FrameSelection frames;
  // Radii of the bone ellipsoids in Gaussian standard deviations (> 0).
  double bone_ellipsoid_sigmas = 1.0;
  // Subdivision level of the unit icosphere of each bone ellipsoid (0..4;
  // 2 = 320 triangles per bone).
  int bone_ellipsoid_subdivisions = 2;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// Canonical surface of the model's SDF (marching cubes at the zero level,
// largest component if asked) with vertex colours from the colour MLP.
// stats (optional): the marching-cubes evaluation counts.
TriangleMesh ExtractCanonicalMesh(const Model& model, const ExtractOptions& options,
                                  MarchingCubesStats* stats = nullptr);

// The SDF MLP as a FieldBatchFunction (for MarchingCubes).
FieldBatchFunction ModelSdfFunction(const Model& model);

// Vertex colours (3 x V, uint8) of canonical points from the colour MLP, with
// view direction (0, 0, 1) and the appearance code of `video` (zeros if -1
// or out of range).
Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> CanonicalColors(const Model& model,
                                                               const Eigen::Matrix3Xd& points,
                                                               int video);

// Delta-skinning logits of the forward warps at canonical points (B x n:
// MLP_Delta with the rest-pose code omega^*), or a 0 x n matrix when the
// model has no delta skinning or its output is identically zero.
Eigen::MatrixXd ForwardDeltaLogits(const Model& model, const Eigen::Matrix3Xd& points);

// The canonical mesh posed at frame `frame` of video `video`, in that frame's
// camera coordinates (forward warp with rest bones and the forward delta
// logits, then G^t). Faces and colours are those of `canonical`.
TriangleMesh ArticulateMesh(const Model& model, const TriangleMesh& canonical, int video,
                            int frame);

// Skinning weights (B x V) of canonical points with the rest bones
// (softmax of the Gaussian logits plus the forward delta logits, Eq. 14;
// they do not depend on the frame). Empty (0 x V) if B = 0.
Eigen::MatrixXd SkinningWeightsAt(const Model& model, const Eigen::Matrix3Xd& points);

// Canonical embedding psi (16 x V, Eq. 15) of canonical points: the
// embedding MLP's raw output (the feature matcher compares directions, so
// normalise before comparing with pixel features).
Eigen::MatrixXd EmbeddingAt(const Model& model, const Eigen::Matrix3Xd& points);

// `mesh` (canonical or posed, model units) in dataset units: vertices
// times model.scene_scale().
TriangleMesh MeshInDatasetUnits(const Model& model, TriangleMesh mesh);

// Colour of bone b in the fixed palette used by the inspection files.
Eigen::Matrix<std::uint8_t, 3, 1> BonePaletteColor(int bone);

// The canonical mesh recoloured by dominant bone (palette above).
TriangleMesh ColorByDominantBone(const TriangleMesh& canonical, const Eigen::MatrixXd& weights);

// One ellipsoid per rest bone (centre C_b, axes V_b, radii sigmas * exp(log_s)),
// coloured with the palette, merged into one mesh. Empty if B = 0.
TriangleMesh BoneEllipsoids(const Model& model, double sigmas, int subdivisions);

// Summary of a WriteExtraction run.
struct ExtractionSummary {
  int canonical_vertices = 0;
  int canonical_faces = 0;
  int frames_written = 0;
  double canonical_seconds = 0.0;   // marching cubes + component + colours
  double articulate_seconds = 0.0;  // all frames, including writing
};

// Writes the files listed at the top of this header into out_dir (created if
// missing), meshes in dataset units. Every file is written atomically; the
// function throws InputError (nothing written) if the level set is empty in
// the bounds.
// progress (optional) is called after the canonical mesh (done = 0) and
// after each articulated frame with (frames done, frames selected).
ExtractionSummary WriteExtraction(
    const Model& model, const ExtractOptions& options, const std::string& out_dir,
    const std::function<void(int done, int total)>& progress = nullptr);

// Axis-aligned bounds of the model's surface from a coarse extraction
// (resolution cells on the longest axis of `bounds`, largest component), for
// the solver's canonical-bounds refresh. Returns an empty box if the level set
// does not cross the grid. (Keeping the smaller components here too was
// measured and not kept: benchmarks/log/2026-11.md, "Stage 3 and detached
// parts".)
Eigen::AlignedBox3d SurfaceBounds(const Model& model, const Eigen::AlignedBox3d& bounds,
                                  int resolution = 48);

// The canonical bounds of the solver's refresh (and of `banmo render`'s
// automatic box): the surface's bounds (SurfaceBounds, resolution 48,
// largest component) inside `search`, plus 10 % of its size and 0.02 on
// every side, clipped to [-2, 2]^3. Returns `search` when the level set does
// not cross the grid (e.g. an untrained model) or the clipped box is empty.
Eigen::AlignedBox3d CanonicalBoundsFromSurface(
    const Model& model,
    const Eigen::AlignedBox3d& search = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-2.0),
                                                            Eigen::Vector3d::Constant(2.0)));

// The canonical box to extract a model's surface from: the box its training
// sampled (Model::canonical_bounds, stored in the model file by
// `banmo solve`) when the model has one, else [-1, 1]^3 (a model of an
// older format, or an untrained one). Outside the trained box the field was
// never trained, and the object may reach beyond [-1, 1]^3 (docs/extract.md).
// A stored box that is not valid (geometry/box.h) fails a CHECK: the model
// file refuses such boxes and the solver never sets one.
Eigen::AlignedBox3d ExtractionBounds(const Model& model);

}  // namespace banmo
