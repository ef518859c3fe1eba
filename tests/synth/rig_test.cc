// Rigs: skinning, the built-in procedural creatures, glTF loading (Fox).
#include "banmo/synth/rig.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "banmo/synth/gltf_rig.h"
#include "banmo/synth/procedural_rig.h"
#include "banmo/synth/rig_library.h"
#include "banmo/util/error.h"

namespace banmo::synth {
namespace {

const std::string kFox = BANMO_SHARED_DIR "/data/gltf/Fox/Fox.glb";

// Two joints on the x axis (root at 0, child at 1), a vertex at x = 2
// weighted 0.5 / 0.5: known LBS answers.
Rig TwoJointRig() {
  Rig rig;
  rig.nodes.resize(2);
  rig.nodes[1].parent = 0;
  rig.nodes[1].translation = Eigen::Vector3d(1, 0, 0);
  rig.influences.resize(2);
  rig.influences[0].node = 0;
  rig.influences[1].node = 1;
  rig.influences[1].inverse_bind.topRightCorner<3, 1>() = Eigen::Vector3d(-1, 0, 0);
  rig.rest_vertices.resize(3, 3);
  rig.rest_vertices << 2, 0, 0, 0, 1, 0, 0, 0, 1;
  rig.faces.resize(3, 1);
  rig.faces << 0, 1, 2;
  rig.vertex_influences.setConstant(kMaxVertexInfluences, 3, -1);
  rig.vertex_weights.setZero(kMaxVertexInfluences, 3);
  rig.vertex_influences(0, 0) = 0, rig.vertex_influences(1, 0) = 1;
  rig.vertex_weights(0, 0) = 0.5f, rig.vertex_weights(1, 0) = 0.5f;
  for (int i = 1; i < 3; ++i) rig.vertex_influences(0, i) = 0, rig.vertex_weights(0, i) = 1;
  rig.vertex_colors.setOnes(3, 3);
  rig.face_material = {0};
  rig.materials.resize(1);
  Animation anim;
  anim.name = "bend";
  AnimationChannel c;
  c.node = 1;
  c.path = ChannelPath::kRotation;
  c.times = {0, 1};
  const Eigen::Quaterniond q(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  c.values.resize(4, 2);
  c.values.col(0) << 0, 0, 0, 1;
  c.values.col(1) << q.x(), q.y(), q.z(), q.w();
  anim.channels.push_back(c);
  rig.animations.push_back(anim);
  return rig;
}

TEST(PoseRig, LinearBlendSkinningKnownAnswer) {
  const Rig rig = TwoJointRig();
  ASSERT_EQ(rig.Validate(), "");
  // Rest: unchanged.
  const Eigen::Matrix3Xd rest = PoseRig(rig, &rig.animations[0], 0);
  EXPECT_LT((rest - rig.rest_vertices).norm(), 1e-12);
  // Child rotated 90 degrees about z at t = 1: the child alone moves (2,0,0)
  // to (1,1,0); the blend is 0.5 (2,0,0) + 0.5 (1,1,0) = (1.5, 0.5, 0).
  const Eigen::Matrix3Xd posed = PoseRig(rig, &rig.animations[0], 1);
  EXPECT_LT((posed.col(0) - Eigen::Vector3d(1.5, 0.5, 0)).norm(), 1e-12);
  EXPECT_LT((posed.col(1) - rig.rest_vertices.col(1)).norm(), 1e-12);
}

TEST(PoseRig, MorphTargetsAddWeightedDeltas) {
  Rig rig = TwoJointRig();
  rig.nodes[0].morph_weights = Eigen::VectorXd::Zero(1);
  RigMorphGroup g;
  g.node = 0;
  g.vertices = {1};
  g.deltas.push_back(Eigen::Matrix3Xd(Eigen::Vector3d(0, 0, 2)));
  rig.morph_groups.push_back(g);
  AnimationChannel w;
  w.node = 0;
  w.path = ChannelPath::kWeights;
  w.times = {0, 1};
  w.values.resize(1, 2);
  w.values << 0, 1;
  rig.animations[0].channels.push_back(w);
  ASSERT_EQ(rig.Validate(), "");
  const Eigen::Matrix3Xd posed = PoseRig(rig, &rig.animations[0], 0.25);
  EXPECT_LT((posed.col(1) - Eigen::Vector3d(0, 1, 0.5)).norm(), 1e-12);
}

TEST(ProceduralRig, BuiltinsAreValidSkinnedAndAnimated) {
  const std::vector<std::string> names = BuiltinRigNames();
  ASSERT_EQ(names, (std::vector<std::string>{"bird", "hand", "quadruped"}));
  for (const auto& name : names) {
    const Rig rig = LoadRig(name);
    EXPECT_EQ(rig.Validate(), "") << name;
    EXPECT_GT(rig.NumFaces(), 5000) << name;
    ASSERT_EQ(rig.animations.size(), 1u) << name;
    // The animation loops: first and last poses agree (1e-9: rounding).
    const Animation& a = rig.animations[0];
    const Eigen::Matrix3Xd p0 = PoseRig(rig, &a, a.StartTime());
    const Eigen::Matrix3Xd p1 = PoseRig(rig, &a, a.EndTime());
    EXPECT_LT((p0 - p1).cwiseAbs().maxCoeff(), 1e-9) << name;
    // And it articulates: some vertex moves by > 5 % of the rig's size.
    const double size =
        (rig.rest_vertices.rowwise().maxCoeff() - rig.rest_vertices.rowwise().minCoeff())
            .maxCoeff();
    const Eigen::Matrix3Xd pm = PoseRig(rig, &a, a.StartTime() + 0.5 * a.Duration());
    const Eigen::Matrix3Xd pq = PoseRig(rig, &a, a.StartTime() + 0.25 * a.Duration());
    const double moved =
        std::max((pm - p0).colwise().norm().maxCoeff(), (pq - p0).colwise().norm().maxCoeff());
    EXPECT_GT(moved, 0.05 * size) << name;
    // Colourful: the per-vertex colours vary over the surface.
    Eigen::Array3f stddev = ((rig.vertex_colors.colwise() - rig.vertex_colors.rowwise().mean())
                                 .array()
                                 .square()
                                 .rowwise()
                                 .mean())
                                .sqrt();
    EXPECT_GT(stddev.minCoeff(), 0.05f) << name;
  }
}

TEST(ProceduralRig, BirdWingsFlapWithALargeAmplitude) {
  const Rig rig = LoadRig("bird");
  const Animation& a = rig.animations[0];
  // Wing-tip height range over a loop (vertices with |z| > 1.3 in rig units).
  double lo = 1e9, hi = -1e9;
  for (int k = 0; k < 16; ++k) {
    const Eigen::Matrix3Xd p = PoseRig(rig, &a, a.Duration() * k / 16);
    for (int i = 0; i < rig.NumVertices(); ++i) {
      if (std::abs(rig.rest_vertices(2, i)) < 1.3) continue;
      lo = std::min(lo, p(1, i));
      hi = std::max(hi, p(1, i));
    }
  }
  // The rest wing span is ~3 units; the tips sweep over more than 2 units.
  EXPECT_GT(hi - lo, 2.0);
}

TEST(ProceduralRig, HandThumbAndIndexTouchAtThePinch) {
  const Rig rig = LoadRig("hand");
  const Animation& a = rig.animations[0];
  // Vertices mostly skinned to the index distal and thumb IP joints.
  auto dominant = [&](int i) {
    return rig.nodes[rig.influences[rig.vertex_influences(0, i)].node].name;
  };
  std::vector<int> index_tip, thumb_tip;
  for (int i = 0; i < rig.NumVertices(); ++i) {
    if (dominant(i) == "index_dip") index_tip.push_back(i);
    if (dominant(i) == "thumb_ip") thumb_tip.push_back(i);
  }
  ASSERT_FALSE(index_tip.empty());
  ASSERT_FALSE(thumb_tip.empty());
  auto min_distance = [&](double t) {
    const Eigen::Matrix3Xd p = PoseRig(rig, &a, t);
    double d = 1e9;
    for (int i : index_tip) {
      for (int j : thumb_tip) d = std::min(d, (p.col(i) - p.col(j)).norm());
    }
    return d;
  };
  // Pinched at t = duration / 4: the surfaces meet (closest vertices within
  // one meshing cell, 0.014); open at 3/4: far apart (> 0.3).
  EXPECT_LT(min_distance(0.25 * a.Duration()), 0.014);
  EXPECT_GT(min_distance(0.75 * a.Duration()), 0.3);
}

TEST(ProceduralRig, BadDefinitionsNameTheKey) {
  const std::string base = BuiltinRigYaml("quadruped");
  try {
    BuildProceduralRig(base + "\ncolour: red\n", "test.yaml");
    FAIL() << "unknown key accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("test.yaml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("colour"), std::string::npos);
  }
  std::string bad_joint = base;
  bad_joint.replace(bad_joint.find("joint: tail_tip, type"), 14, "joint: nowhere");
  EXPECT_THROW(BuildProceduralRig(bad_joint, "test.yaml"), InputError);
  EXPECT_THROW(BuildProceduralRig("name: x\n", "test.yaml"), InputError);
  EXPECT_THROW(BuildProceduralRig("[unclosed", "test.yaml"), InputError);
}

TEST(RigLibrary, UnknownRigAndMissingFileAreInputErrors) {
  try {
    LoadRig("dragon");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dragon"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("quadruped"), std::string::npos);
  }
  try {
    LoadRig("/nonexistent/model.glb");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/model.glb"), std::string::npos);
  }
}

TEST(MeshLevelSet, SphereIsAccurateAndOutwardOriented) {
  const double r = 0.7;
  const TriangleMesh m =
      MeshLevelSet([&](const Eigen::Vector3d& p) { return p.norm() - r; },
                   Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1), 0.05);
  ASSERT_GT(m.NumFaces(), 1000);
  // Projected vertices lie on the sphere (1e-6: Newton on an exact SDF).
  EXPECT_LT((m.vertices.colwise().norm().array() - r).abs().maxCoeff(), 1e-6);
  // Outward faces: the signed volume is positive and close to 4/3 pi r^3
  // (within 1 %: flat facets of a 0.05 grid).
  double volume = 0;
  for (int f = 0; f < m.NumFaces(); ++f) {
    volume += m.vertices.col(m.faces(0, f))
                  .dot(m.vertices.col(m.faces(1, f)).cross(m.vertices.col(m.faces(2, f)))) /
              6;
  }
  EXPECT_NEAR(volume, 4.0 / 3 * M_PI * r * r * r, 0.01 * 4.0 / 3 * M_PI * r * r * r);
}

TEST(GltfRig, FoxLoadsWithItsThreeAnimations) {
  const Rig rig = LoadGltfRig(kFox);
  EXPECT_EQ(rig.Validate(), "");
  EXPECT_EQ(rig.NumFaces(), 576);
  ASSERT_EQ(rig.animations.size(), 3u);
  EXPECT_EQ(rig.animations[0].name, "Survey");
  EXPECT_EQ(rig.animations[1].name, "Walk");
  EXPECT_EQ(rig.animations[2].name, "Run");
  ASSERT_EQ(rig.textures.size(), 1u);
  EXPECT_GE(rig.uvs.cols(), 1);
  // The inverse bind matrices match the rest pose: skinning matrices are the
  // identity there (1e-4: the file stores floats of magnitude ~100).
  const auto global = NodeGlobalTransforms(rig, nullptr, 0);
  for (const auto& inf : rig.influences) {
    EXPECT_LT(
        (global[inf.node] * inf.inverse_bind - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(),
        1e-4);
  }
  // Every animation moves the mesh.
  for (const auto& a : rig.animations) {
    const Eigen::Matrix3Xd p = PoseRig(rig, &a, a.StartTime() + 0.3 * a.Duration());
    EXPECT_GT((p - rig.rest_vertices).colwise().norm().maxCoeff(), 5.0) << a.name;
  }
}

TEST(GltfRig, BadFilesAreInputErrors) {
  EXPECT_THROW(LoadGltfRig("/nonexistent.glb"), InputError);
  EXPECT_THROW(LoadGltfRig(BANMO_SHARED_DIR "/data/gltf/Fox/LICENSE.txt"), InputError);
  // A .glb that is not one (the license text under a .glb name).
  const std::string fake = testing::TempDir() + "/not_a_model.glb";
  FILE* f = std::fopen(fake.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  std::fputs("this is not a glb", f);
  std::fclose(f);
  try {
    LoadGltfRig(fake);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fake), std::string::npos);
  }
}

}  // namespace
}  // namespace banmo::synth
