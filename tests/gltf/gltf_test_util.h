// Test helpers for the glTF export: a hand-built model whose bones really
// move the mesh, and an independent glTF skinning evaluator written from the
// glTF 2.0 specification (sections 3.5 nodes/TRS, 3.7.3 skins, 3.11
// animations, Appendix: interpolation) that shares no code with the
// exporter.
#pragma once

#include <tiny_gltf.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "banmo/model/model.h"

namespace banmo::testing {

// A model with `num_bones` bones on the initial SDF sphere (radius 0.5) of a
// small field: rest bones spread over a sphere of radius 0.3 with random
// orientations and anisotropic scales, visible non-identity bone transforms
// (rotations up to ~0.6 rad, translations up to 0.08) and root poses in front
// of the camera, in 2 videos of 3 and 4 frames. Deterministic in seed.
// With `delta_skinning`, the model also has a delta-skinning MLP with random
// weights (so its forward logits are not zero).
inline std::unique_ptr<Model> MakeExportTestModel(int num_bones, uint32_t seed,
                                                  bool delta_skinning = false) {
  ModelOptions o;
  o.num_bones = num_bones;
  o.delta_skinning.enabled = delta_skinning;
  o.delta_skinning.width = 8;
  o.delta_skinning.hidden_layers = 1;
  o.delta_skinning.num_bands = 2;
  o.field.position_encoding.num_bands = 2;
  o.field.sdf_width = 16;
  o.field.sdf_layers = 2;
  o.field.geometry_feature_dim = 4;
  o.field.color_width = 8;
  o.field.color_layers = 1;
  o.field.embedding_width = 8;
  o.field.embedding_layers = 1;
  o.field.appearance_code_dim = 2;
  PinholeCamera camera;
  camera.width = camera.height = 32;
  camera.intrinsics = Eigen::Vector4d(30, 30, 16, 16);
  auto model = std::make_unique<Model>(o, std::vector<int>{3, 4},
                                       std::vector<PinholeCamera>{camera, camera});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random_quaternion = [&](double max_angle) {
    Eigen::Vector3d axis(u(rng), u(rng), u(rng));
    axis.normalize();
    return Eigen::Quaterniond(Eigen::AngleAxisd(max_angle * u(rng), axis));
  };
  for (int b = 0; b < num_bones; ++b) {
    double* bone = model->bones() + kBoneSize * b;
    // Fibonacci sphere of radius 0.3.
    const double z = 1.0 - 2.0 * (b + 0.5) / num_bones;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = 2.399963229728653 * b;
    bone[kBoneCenter + 0] = 0.3 * r * std::cos(phi);
    bone[kBoneCenter + 1] = 0.3 * r * std::sin(phi);
    bone[kBoneCenter + 2] = 0.3 * z;
    const Eigen::Quaterniond q = random_quaternion(3.0);
    bone[kBoneQw] = q.w();
    bone[kBoneQw + 1] = q.x();
    bone[kBoneQw + 2] = q.y();
    bone[kBoneQw + 3] = q.z();
    for (int k = 0; k < 3; ++k) bone[kBoneLogScale + k] = std::log(0.18 + 0.06 * u(rng));
  }
  if (delta_skinning) {
    std::normal_distribution<double> n(0.0, 0.5);
    for (int i = 0; i < model->delta_skinning_size(); ++i)
      model->delta_skinning_params()[i] = n(rng);
  }
  for (int v = 0; v < model->num_videos(); ++v) {
    for (size_t t = 0; t < model->video(v).frames.size(); ++t) {
      FrameParameters& f = model->frame(v, static_cast<int>(t));
      f.root_init = PoseFromAngleAxis(Eigen::Vector3d(0.4 * u(rng), 0.4 * u(rng), 0.4 * u(rng)),
                                      Eigen::Vector3d(0.2 * u(rng), 0.2 * u(rng), 3.0));
      f.root_delta = PoseFromAngleAxis(Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 0),
                                       Eigen::Vector3d(0.02 * u(rng), 0, 0));
      for (int b = 0; b < num_bones; ++b) {
        const Pose p =
            PoseFromAngleAxis(Eigen::Vector3d(0.35 * u(rng), 0.35 * u(rng), 0.35 * u(rng)),
                              Eigen::Vector3d(0.08 * u(rng), 0.08 * u(rng), 0.08 * u(rng)));
        std::copy(p.data(), p.data() + kPoseSize, f.bones_t.data() + kPoseSize * b);
      }
    }
  }
  return model;
}

// Time of key t as stored in the file (float32 seconds): sampling at the
// double t / fps could fall just before the key.
inline double KeyTime(int t, double fps) { return static_cast<float>(t / fps); }

// ---- Independent glTF evaluation (from the spec, not the exporter) ----

// Accessor as (components x count) doubles; tightly packed or strided views;
// normalised integers mapped to [0, 1].
inline Eigen::MatrixXd ReadAccessor(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors.at(index);
  const tinygltf::BufferView& v = m.bufferViews.at(a.bufferView);
  const tinygltf::Buffer& buf = m.buffers.at(v.buffer);
  const int comps = tinygltf::GetNumComponentsInType(a.type);
  const int size = tinygltf::GetComponentSizeInBytes(a.componentType);
  const size_t stride = v.byteStride ? v.byteStride : static_cast<size_t>(comps) * size;
  Eigen::MatrixXd out(comps, a.count);
  for (size_t i = 0; i < a.count; ++i) {
    const unsigned char* e = buf.data.data() + v.byteOffset + a.byteOffset + i * stride;
    for (int c = 0; c < comps; ++c) {
      const unsigned char* p = e + c * size;
      double x = 0;
      if (a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT) {
        float f;
        std::memcpy(&f, p, 4);
        x = f;
      } else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) {
        x = a.normalized ? *p / 255.0 : *p;
      } else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
        uint16_t s;
        std::memcpy(&s, p, 2);
        x = a.normalized ? s / 65535.0 : s;
      } else if (a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
        uint32_t s;
        std::memcpy(&s, p, 4);
        x = s;
      } else {
        throw std::runtime_error("ReadAccessor: unsupported component type");
      }
      out(c, i) = x;
    }
  }
  return out;
}

// Spec slerp between unit quaternions [x, y, z, w] (shortest arc).
inline Eigen::Vector4d SpecSlerp(Eigen::Vector4d a, Eigen::Vector4d b, double s) {
  double d = a.dot(b);
  if (d < 0) {
    b = -b;
    d = -d;
  }
  if (d > 0.9995) return ((1 - s) * a + s * b).normalized();
  const double angle = std::acos(d);
  return ((std::sin((1 - s) * angle) * a + std::sin(s * angle) * b) / std::sin(angle)).normalized();
}

// Value of sampler `sampler` of `anim` at time t (LINEAR or STEP; clamped).
inline Eigen::VectorXd SampleAt(const tinygltf::Model& m, const tinygltf::Animation& anim,
                                int sampler, bool rotation, double t) {
  const tinygltf::AnimationSampler& s = anim.samplers.at(sampler);
  const Eigen::MatrixXd times = ReadAccessor(m, s.input);
  const Eigen::MatrixXd values = ReadAccessor(m, s.output);
  const Eigen::Index n = times.cols();
  if (t <= times(0, 0)) return values.col(0);
  if (t >= times(0, n - 1)) return values.col(n - 1);
  Eigen::Index k = 0;
  while (times(0, k + 1) <= t) ++k;
  if (s.interpolation == "STEP") return values.col(k);
  const double a = (t - times(0, k)) / (times(0, k + 1) - times(0, k));
  if (rotation) return SpecSlerp(values.col(k), values.col(k + 1), a);
  return (1 - a) * values.col(k) + a * values.col(k + 1);
}

// Global transforms (world_from_node) of all nodes of the default scene at
// time t of animation `animation` (-1: the rest pose): local = T * R * S
// (or `matrix`), global = parent global * local.
inline std::vector<Eigen::Matrix4d> SpecNodeGlobals(const tinygltf::Model& m, int animation,
                                                    double t) {
  const size_t n = m.nodes.size();
  std::vector<Eigen::Vector3d> tr(n, Eigen::Vector3d::Zero()), sc(n, Eigen::Vector3d::Ones());
  std::vector<Eigen::Vector4d> ro(n, Eigen::Vector4d(0, 0, 0, 1));
  for (size_t i = 0; i < n; ++i) {
    const tinygltf::Node& node = m.nodes[i];
    if (node.translation.size() == 3) tr[i] = Eigen::Vector3d(node.translation.data());
    if (node.scale.size() == 3) sc[i] = Eigen::Vector3d(node.scale.data());
    if (node.rotation.size() == 4) ro[i] = Eigen::Vector4d(node.rotation.data());
  }
  if (animation >= 0) {
    const tinygltf::Animation& anim = m.animations.at(animation);
    for (const tinygltf::AnimationChannel& c : anim.channels) {
      if (c.target_path == "translation")
        tr[c.target_node] = SampleAt(m, anim, c.sampler, false, t);
      if (c.target_path == "scale") sc[c.target_node] = SampleAt(m, anim, c.sampler, false, t);
      if (c.target_path == "rotation") ro[c.target_node] = SampleAt(m, anim, c.sampler, true, t);
    }
  }
  std::vector<Eigen::Matrix4d> global(n, Eigen::Matrix4d::Identity());
  std::function<void(int, const Eigen::Matrix4d&)> visit = [&](int i, const Eigen::Matrix4d& p) {
    const tinygltf::Node& node = m.nodes[i];
    Eigen::Matrix4d local = Eigen::Matrix4d::Identity();
    if (node.matrix.size() == 16) {
      local = Eigen::Map<const Eigen::Matrix4d>(node.matrix.data());  // column-major
    } else {
      const Eigen::Quaterniond q(ro[i][3], ro[i][0], ro[i][1], ro[i][2]);
      local.topLeftCorner<3, 3>() = q.normalized().toRotationMatrix() * sc[i].asDiagonal();
      local.topRightCorner<3, 1>() = tr[i];
    }
    global[i] = p * local;
    for (int c : node.children) visit(c, global[i]);
  };
  const tinygltf::Scene& scene = m.scenes.at(m.defaultScene < 0 ? 0 : m.defaultScene);
  for (int root : scene.nodes) visit(root, Eigen::Matrix4d::Identity());
  return global;
}

// World positions (3 x V) of the first primitive of the first node with a
// mesh, posed at time t of `animation`: skinned (spec: joint matrix =
// inverse(global(mesh node)) * global(joint) * inverseBind; the mesh node's
// transform is then ignored, i.e. positions end in world via the joints) or
// rigid (global(mesh node) * position).
inline Eigen::Matrix3Xd SpecPosedPositions(const tinygltf::Model& m, int animation, double t) {
  const std::vector<Eigen::Matrix4d> global = SpecNodeGlobals(m, animation, t);
  int mesh_node = -1;
  for (size_t i = 0; i < m.nodes.size() && mesh_node < 0; ++i) {
    if (m.nodes[i].mesh >= 0) mesh_node = static_cast<int>(i);
  }
  const tinygltf::Node& node = m.nodes.at(mesh_node);
  const tinygltf::Primitive& prim = m.meshes.at(node.mesh).primitives.at(0);
  const Eigen::MatrixXd x = ReadAccessor(m, prim.attributes.at("POSITION"));
  Eigen::Matrix3Xd out(3, x.cols());
  if (node.skin < 0) {
    for (Eigen::Index i = 0; i < x.cols(); ++i) {
      out.col(i) = (global[mesh_node] * x.col(i).homogeneous()).head<3>();
    }
    return out;
  }
  const tinygltf::Skin& skin = m.skins.at(node.skin);
  const Eigen::MatrixXd ibm = ReadAccessor(m, skin.inverseBindMatrices);
  std::vector<Eigen::Matrix4d> joint(skin.joints.size());
  const Eigen::Matrix4d mesh_inverse = global[mesh_node].inverse();
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    joint[j] = mesh_inverse * global[skin.joints[j]] *
               Eigen::Map<const Eigen::Matrix4d>(ibm.col(static_cast<Eigen::Index>(j)).data());
  }
  const Eigen::MatrixXd joints = ReadAccessor(m, prim.attributes.at("JOINTS_0"));
  const Eigen::MatrixXd weights = ReadAccessor(m, prim.attributes.at("WEIGHTS_0"));
  for (Eigen::Index i = 0; i < x.cols(); ++i) {
    Eigen::Matrix4d skin_matrix = Eigen::Matrix4d::Zero();
    for (int k = 0; k < 4; ++k) {
      skin_matrix += weights(k, i) * joint[static_cast<size_t>(joints(k, i))];
    }
    // Rendered with the mesh node's global (spec: the skinned vertex is in the
    // mesh node's space, then drawn with its global transform).
    out.col(i) = (global[mesh_node] * skin_matrix * x.col(i).homogeneous()).head<3>();
  }
  return out;
}

// glTF world (y up) -> OpenCV camera axes: undo the exporter's fixed 180
// degree rotation about x.
inline Eigen::Matrix3Xd GltfToOpenCv(const Eigen::Matrix3Xd& x) {
  return Eigen::Vector3d(1, -1, -1).asDiagonal() * x;
}

}  // namespace banmo::testing
