// A skinned, animated mesh ("rig"): the source of every synthetic scene.
//
// A rig is a node hierarchy (glTF style: each node has a rest local
// translation / rotation / scale and an optional parent), a rest mesh with
// per-vertex colours or UVs + textures, and linear-blend-skinning weights of
// each vertex to a list of "influences". An influence is a node together with
// its inverse bind matrix (the glTF skin joint); a mesh rigidly attached to a
// node is one influence with weight 1 and the node's rest global transform's
// inverse as inverse bind matrix. Posing at time t:
//   G_n(t)  = G_parent(n)(t) * T_n(t) R_n(t) S_n(t)            (node globals)
//   x(t)    = sum_i w_i  G_node(i)(t) * inverse_bind_i * x_rest  (LBS)
// with T/R/S from the animation channels where present and the rest values
// elsewhere. Morph targets (position deltas) are applied to x_rest before
// skinning: x_rest' = x_rest + sum_k weight_k(t) * delta_k.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "banmo/geometry/mesh.h"
#include "banmo/synth/animation.h"

namespace banmo::synth {

// Maximum number of skinning influences kept per vertex (glTF JOINTS_0 and
// JOINTS_1 give up to 8).
inline constexpr int kMaxVertexInfluences = 8;

struct RigNode {
  std::string name;
  int parent = -1;                                        // index into Rig::nodes, -1 for a root
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // rest local T
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // rest local R
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();               // rest local S
  // Rest morph-target weights of the mesh on this node (glTF mesh.weights or
  // node.weights); empty if the node carries no morph targets.
  Eigen::VectorXd morph_weights;
};

struct RigInfluence {
  int node = -1;                                               // index into Rig::nodes
  Eigen::Matrix4d inverse_bind = Eigen::Matrix4d::Identity();  // bind space <- node space
};

// Surface appearance of a set of faces.
struct RigMaterial {
  Eigen::Vector4d base_color = Eigen::Vector4d::Ones();  // RGBA factor in [0, 1]
  int texture = -1;                                      // index into Rig::textures, -1 if none
};

// Morph targets of a group of vertices, driven by the weights of one node.
struct RigMorphGroup {
  int node = -1;                         // whose (animated) weights drive it
  std::vector<int> vertices;             // rig vertex indices
  std::vector<Eigen::Matrix3Xd> deltas;  // per target: 3 x vertices.size() offsets
};

struct Rig {
  std::string name;
  std::vector<RigNode> nodes;
  std::vector<RigInfluence> influences;

  // Rest mesh in bind space: vertices (3 x V), faces (3 x F, CCW from outside).
  Eigen::Matrix3Xd rest_vertices;
  Eigen::Matrix3Xi faces;
  // Skinning: per vertex up to kMaxVertexInfluences (influence index, weight)
  // pairs; unused slots have index -1 and weight 0; weights sum to 1.
  Eigen::Matrix<int, kMaxVertexInfluences, Eigen::Dynamic> vertex_influences;
  Eigen::Matrix<float, kMaxVertexInfluences, Eigen::Dynamic> vertex_weights;

  // Appearance: per-vertex RGB in [0, 1] (display values; multiplied with the
  // material colour and texture), per-vertex UVs (2 x V, glTF convention:
  // (0, 0) is the top-left of the image; empty if no texture is used),
  // per-face material index, materials and RGB8 textures (CV_8UC3, RGB order).
  Eigen::Matrix3Xf vertex_colors;
  Eigen::Matrix2Xf uvs;
  std::vector<int> face_material;
  std::vector<RigMaterial> materials;
  std::vector<cv::Mat> textures;

  std::vector<RigMorphGroup> morph_groups;
  std::vector<Animation> animations;

  int NumVertices() const { return static_cast<int>(rest_vertices.cols()); }
  int NumFaces() const { return static_cast<int>(faces.cols()); }
  // Index of the animation called `name`, or -1.
  int FindAnimation(const std::string& name) const;
  // Checks all indices, sizes, weight sums and finiteness; returns an empty
  // string when valid, otherwise the first problem found.
  std::string Validate() const;
};

// Global (world <- node) 4x4 transforms of all nodes at time t of
// `animation` (nullptr: rest pose). t is used as given (no looping: call
// Animation::WrapTime first for loops). Also returns the animated morph
// weights per node when `morph_weights` is not null.
std::vector<Eigen::Matrix4d> NodeGlobalTransforms(
    const Rig& rig, const Animation* animation, double t,
    std::vector<Eigen::VectorXd>* morph_weights = nullptr);

// Posed vertices (3 x V) at time t by morph targets + linear blend skinning.
Eigen::Matrix3Xd PoseRig(const Rig& rig, const Animation* animation, double t);

// Linear blend skinning alone: vertices (3 x V) from rest vertices and one
// 4x4 skinning matrix per influence (G_node * inverse_bind).
Eigen::Matrix3Xd LinearBlendSkinning(const Rig& rig, const Eigen::Matrix3Xd& rest_vertices,
                                     const std::vector<Eigen::Matrix4d>& skin_matrices);

// Per-vertex colours of the rest mesh as RGB in [0, 1]: vertex colour x
// material factor x texture sampled (bilinear, repeat) at the vertex UV.
Eigen::Matrix3Xf RigVertexColors(const Rig& rig);

// Bilinear, repeat-wrapped lookup of an RGB8 texture at glTF UV (u, v);
// returns RGB in [0, 1].
Eigen::Vector3f SampleTexture(const cv::Mat& texture, float u, float v);

// Area-weighted vertex normals (3 x V, unit length; zero for isolated vertices).
Eigen::Matrix3Xd VertexNormals(const Eigen::Matrix3Xd& vertices, const Eigen::Matrix3Xi& faces);

}  // namespace banmo::synth
