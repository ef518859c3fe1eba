// Animatable glTF 2.0 export of a BANMo model (docs/export.md).
//
// The model's forward warp (deform/bones.h, extract/extract.h) is linear
// blend skinning with rest-bone weights followed by the root pose:
//   x_in_camera = G^t * sum_b w_b(X*) J_b^t X*,
//   w = softmax of the rest Gaussian logits (SkinningWeightsAt),
//   J_b^t = posed_from_rest of bone b, G^t = model.RootPose(v, t)
//   (camera_from_root, OpenCV axes: x right, y down, z forward).
// glTF skinning evaluates sum_i w_i M_i x with joint matrices M_i, so the
// warp is represented exactly, up to glTF's four influences per vertex
// (JOINTS_0 / WEIGHTS_0: the top-4 rest weights, renormalised) and float32
// storage. The file holds:
//
//   scene "banmo"
//   node "opencv_to_gltf"   fixed rotation A = 180 deg about x, so a viewer
//   |                       with glTF's y-up convention shows the camera's
//   |                       "up" (-y in OpenCV) as up
//   +- node "root"          animated T/R = G^t (identity at rest)
//   |  +- node "bone_<b>"   one joint per bone; rest T/R = the rest bone
//   |                       frame R_b (centre C_b, orientation V_b);
//   |                       animated T/R = J_b^t * R_b
//   +- (B = 0 only) node "mesh" child of "root", unskinned, fixed rotation
//                           A^{-1} (= A) so the rigid mesh shows A G^t X*
//   node "mesh"             (B > 0) top-level, no transform, skin 0: glTF
//                           ignores a skinned mesh node's own transform
//
// Bind pose = rest pose of the hierarchy: POSITION and NORMAL are the
// canonical mesh expressed in the scene's world frame, A X*, and joint b's
// inverse bind matrix is (A R_b)^{-1}, the inverse of its rest global
// transform. Posed at frame t of video v, joint b's skin matrix is
//   A G^t (J_b^t R_b) (A R_b)^{-1} = A G^t J_b^t A^{-1},
// so the mesh shows A x_in_camera: the articulated mesh of ArticulateMesh in
// that frame's camera coordinates, turned by A. Undo A (negate y and z) to
// compare with `banmo extract` frames.
//
// One animation per video ("video00", ... or the given names), keys at
// t / fps seconds for t = 0..frames-1, translation and rotation channels for
// "root" and every bone (no scale: all transforms are rigid). Rotations are
// glTF quaternions [x, y, z, w] (the model stores [qw, qx, qy, qz, ...],
// geometry/se3.h), sign-aligned with the previous key so LINEAR slerp takes
// the short way.
//
// Units: the file is in the dataset's units. The model works in model units
// (model/model.h: dataset units / s, s = model.scene_scale()), so positions,
// the bones' rest centres and every animated translation are multiplied by
// s (a uniform scale of the scene: rotations and skinning weights do not
// change); the canonical mesh given to BuildGltf is in model units, as
// ExtractCanonicalMesh returns it.
//
// Limitation: with a delta-skinning MLP (frame-dependent weights) the warp is
// not linear blend skinning with fixed weights and glTF cannot represent it;
// the export uses the rest weights (SkinningWeightsAt) only.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "banmo/extract/extract.h"
#include "banmo/geometry/mesh.h"
#include "banmo/model/model.h"

namespace tinygltf {
class Model;
}

namespace banmo {

// glTF allows four influences in JOINTS_0 / WEIGHTS_0.
inline constexpr int kGltfInfluences = 4;

enum class GltfInterpolation { kLinear, kStep };

struct GltfExportOptions {
  // Marching cubes of the canonical mesh and its colours (extract.h). The
  // default grid resolution here is 128 (29k triangles for the Fox run, 36k
  // for the default scene; 256 gives about 4x more); frames is ignored.
  ExtractOptions extract = [] {
    ExtractOptions e;
    e.grid.resolution = 128;
    return e;
  }();
  // Key frames per second of the animations (> 0): frame t is at t / fps s.
  double fps = 10.0;
  // Interpolation of every animation sampler. LINEAR (default) plays smoothly
  // between frames and equals the model exactly at the keys; STEP holds each
  // frame until the next key.
  GltfInterpolation interpolation = GltfInterpolation::kLinear;
  // Animation names, one per video; empty = "video00", "video01", ...
  std::vector<std::string> video_names;
  // Write the vertex colours (COLOR_0, linear RGB = (c / 255)^2.2, the
  // project's display gamma, as synth/gltf_rig.h reads them back).
  bool vertex_colors = true;

  // Throws InputError naming the field on a violated constraint.
  void Check() const;
};

// Top-k skinning influences per vertex: for each column of `weights` (B x V)
// the k largest weights, renormalised to sum 1, in decreasing order. With
// B < k the remaining slots get joint 0 and weight 0. joints, out_weights:
// k x V.
void TopInfluences(const Eigen::MatrixXd& weights, int k, Eigen::MatrixXi* joints,
                   Eigen::MatrixXd* out_weights);

// Counts of a built glTF document.
struct GltfExportSummary {
  int vertices = 0;
  int faces = 0;
  int joints = 0;      // = model bones (0: no skin)
  int animations = 0;  // = videos
  int keyframes = 0;   // over all videos
  // Largest weight mass dropped by the top-4 truncation over the vertices,
  // 1 - (sum of the 4 largest rest weights); 0 when B <= 4.
  double max_dropped_weight = 0.0;
  std::size_t bytes = 0;       // size of the written file (ExportGltf only)
  double mesh_seconds = 0.0;   // canonical mesh + colours
  double build_seconds = 0.0;  // weights, buffers, animations, validation
  double write_seconds = 0.0;  // serialise + atomic write
};

// Builds the glTF document described at the top of this header from the
// model and its canonical mesh (vertex colours used if present and
// options.vertex_colors), then validates it (validate.h). Throws InputError
// if the result is invalid (e.g. non-finite parameters) or the options are.
GltfExportSummary BuildGltf(const Model& model, const TriangleMesh& canonical,
                            const GltfExportOptions& options, tinygltf::Model* out);

// Serialises `gltf` atomically (temporary file + rename, util/atomic_file.h)
// as binary .glb (binary = true) or as .gltf JSON with the buffer embedded
// as a base64 data URI. Returns the bytes written. Throws InputError naming
// the path if it cannot be written (nothing is left behind).
std::size_t WriteGltf(const tinygltf::Model& gltf, const std::string& path, bool binary);

// Loads a .glb or .gltf (by extension). Throws InputError naming the path.
void ReadGltf(const std::string& path, tinygltf::Model* out);

// ExtractCanonicalMesh + BuildGltf + WriteGltf (binary unless `path` ends in
// ".gltf"). Throws InputError (nothing written) if the level set is empty,
// the document is invalid or the path unwritable. progress (optional) gets a
// one-line message after each step.
GltfExportSummary ExportGltf(const Model& model, const GltfExportOptions& options,
                             const std::string& path,
                             const std::function<void(const std::string&)>& progress = nullptr);

}  // namespace banmo
