// glTF export round trip: export a model with visibly moved bones, load the
// file back with tinygltf, pose it at every key frame with an independent
// evaluator written from the glTF spec (gltf_test_util.h) and with the synth
// module's glTF rig loader, and compare with ArticulateMesh. Also the top-4
// truncation error, STEP/LINEAR, rigid models, .gltf output, and the
// validator on hand-broken documents.
#include "banmo/gltf/export.h"

#include <gtest/gtest.h>
#include <tiny_gltf.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "../common/shared_assets.h"
#include "banmo/extract/extract.h"
#include "banmo/gltf/validate.h"
#include "banmo/optim/checkpoint.h"
#include "banmo/synth/gltf_rig.h"
#include "banmo/synth/rig.h"
#include "banmo/util/error.h"
#include "gltf_test_util.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::GltfToOpenCv;
using testing::MakeExportTestModel;
using testing::SpecPosedPositions;

// Float32 storage: the posed meshes lie about 3 units from the camera, and
// every stored quantity (positions, inverse bind matrices, key
// translations and quaternions) carries a relative rounding of 6e-8; a few
// products of such matrices give ~1e-6 absolute. 1e-5 leaves a 10x margin
// while a wrong convention (axis flip, quaternion order, bind matrix
// inverted) gives errors of 1e-2..1.
constexpr double kFloatTolerance = 1e-5;

class GltfExport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("banmo_gltf_export_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    options_.extract.grid.resolution = 40;
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  GltfExportOptions options_;
};

// Top-4 linear blend skinning in double of the same weights as the export
// (the model's rest weights, TopInfluences), posed at (v, t) into camera
// coordinates: the export's target without float rounding.
Eigen::Matrix3Xd TopKLbs(const Model& model, const TriangleMesh& canonical, int v, int t) {
  const Eigen::MatrixXd w = SkinningWeightsAt(model, canonical.vertices);
  Eigen::MatrixXi joints;
  Eigen::MatrixXd weights;
  TopInfluences(w, kGltfInfluences, &joints, &weights);
  const Eigen::Isometry3d g = IsometryFromPose(model.RootPose(v, t).data());
  Eigen::Matrix3Xd out(3, canonical.NumVertices());
  for (int i = 0; i < canonical.NumVertices(); ++i) {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int k = 0; k < kGltfInfluences; ++k) {
      const Eigen::Isometry3d j =
          IsometryFromPose(model.frame(v, t).bones_t.data() + kPoseSize * joints(k, i));
      x += weights(k, i) * (j * canonical.vertices.col(i));
    }
    out.col(i) = g * x;
  }
  return out;
}

double MaxVertexError(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  return (a - b).colwise().norm().maxCoeff();
}

TEST(TopInfluences, KeepsLargestAndRenormalises) {
  Eigen::MatrixXd w(6, 2);
  w.col(0) << 0.05, 0.3, 0.1, 0.2, 0.25, 0.1;
  w.col(1) << 0.5, 0.5, 0, 0, 0, 0;
  Eigen::MatrixXi j;
  Eigen::MatrixXd k;
  TopInfluences(w, 4, &j, &k);
  EXPECT_EQ(j(0, 0), 1);
  EXPECT_EQ(j(1, 0), 4);
  EXPECT_EQ(j(2, 0), 3);
  EXPECT_EQ(j(3, 0), 2);  // tie 0.1 with bone 5: lower index first
  EXPECT_NEAR(k.col(0).sum(), 1.0, 1e-15);
  EXPECT_NEAR(k(0, 0), 0.3 / 0.85, 1e-15);
  EXPECT_NEAR(k(0, 1), 0.5, 1e-15);
  // Fewer bones than slots: padding with joint 0, weight 0.
  TopInfluences(w.topRows(2), 4, &j, &k);
  EXPECT_EQ(j(2, 0), 0);
  EXPECT_EQ(k(2, 0), 0.0);
  EXPECT_NEAR(k.col(0).sum(), 1.0, 1e-15);
}

// The main round trip, on a 10-bone model (> 4, so truncation is exercised).
TEST_F(GltfExport, RoundTripMatchesArticulateMeshUpToTop4Truncation) {
  const auto model = MakeExportTestModel(10, 7);
  const fs::path path = dir_ / "model.glb";
  const GltfExportSummary summary = ExportGltf(*model, options_, path.string());
  ASSERT_TRUE(fs::exists(path));
  EXPECT_EQ(summary.bytes, fs::file_size(path));
  EXPECT_EQ(summary.joints, 10);
  EXPECT_EQ(summary.animations, 2);
  EXPECT_EQ(summary.keyframes, 7);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  ASSERT_EQ(summary.vertices, canonical.NumVertices());
  ASSERT_GT(canonical.NumVertices(), 500);

  tinygltf::Model gltf;
  ReadGltf(path.string(), &gltf);
  EXPECT_TRUE(ValidateGltf(gltf).empty());
  ASSERT_EQ(gltf.animations.size(), 2u);
  EXPECT_EQ(gltf.animations[0].name, "video00");
  EXPECT_EQ(gltf.animations[1].name, "video01");
  ASSERT_EQ(gltf.skins.size(), 1u);
  EXPECT_EQ(gltf.skins[0].joints.size(), 10u);

  // Weight sums: within a float ulp or two of 1 (docs/export.md).
  const Eigen::MatrixXd w =
      testing::ReadAccessor(gltf, gltf.meshes[0].primitives[0].attributes.at("WEIGHTS_0"));
  EXPECT_LE((w.colwise().sum().array() - 1.0).abs().maxCoeff(), 2.4e-7);
  EXPECT_GE(w.minCoeff(), 0.0);

  // The rig loader of the synth module (independent code) as a second check.
  const synth::Rig rig = synth::LoadGltfRig(path.string());
  ASSERT_EQ(rig.NumVertices(), canonical.NumVertices());

  double export_error = 0, truncation_error = 0, total_error = 0, rig_error = 0;
  double skinning_motion = 0;
  for (int v = 0; v < model->num_videos(); ++v) {
    const int anim = rig.FindAnimation(v == 0 ? "video00" : "video01");
    ASSERT_GE(anim, 0);
    for (int t = 0; t < static_cast<int>(model->video(v).frames.size()); ++t) {
      const double time = testing::KeyTime(t, options_.fps);
      const Eigen::Matrix3Xd gltf_posed = GltfToOpenCv(SpecPosedPositions(gltf, v, time));
      const Eigen::Matrix3Xd rig_posed =
          GltfToOpenCv(synth::PoseRig(rig, &rig.animations[anim], time));
      const Eigen::Matrix3Xd full = ArticulateMesh(*model, canonical, v, t).vertices;
      const Eigen::Matrix3Xd top4 = TopKLbs(*model, canonical, v, t);
      export_error = std::max(export_error, MaxVertexError(gltf_posed, top4));
      rig_error = std::max(rig_error, MaxVertexError(rig_posed, top4));
      truncation_error = std::max(truncation_error, MaxVertexError(top4, full));
      total_error = std::max(total_error, MaxVertexError(gltf_posed, full));
      // How far the bones move the mesh relative to the root pose alone.
      const Eigen::Isometry3d g = IsometryFromPose(model->RootPose(v, t).data());
      skinning_motion = std::max(skinning_motion, MaxVertexError(full, g * canonical.vertices));

      // Truncation bound: x_full - x_top4 = (1 - s)(x_dropped - x_top4)
      // with s the kept weight mass, so per vertex
      //   |error| <= (1 - s) * max_{b, b'} |J_b X - J_b' X|.
      const Eigen::MatrixXd w = SkinningWeightsAt(*model, canonical.vertices);
      for (int i = 0; i < canonical.NumVertices(); i += 7) {
        Eigen::VectorXd sorted = w.col(i);
        std::sort(sorted.data(), sorted.data() + sorted.size(), std::greater<double>());
        const double dropped = 1.0 - sorted.head(4).sum();
        double spread = 0;
        for (int a = 0; a < 10; ++a) {
          for (int b = 0; b < 10; ++b) {
            const Eigen::Vector3d za =
                IsometryFromPose(model->frame(v, t).bones_t.data() + kPoseSize * a) *
                canonical.vertices.col(i);
            const Eigen::Vector3d zb =
                IsometryFromPose(model->frame(v, t).bones_t.data() + kPoseSize * b) *
                canonical.vertices.col(i);
            spread = std::max(spread, (za - zb).norm());
          }
        }
        EXPECT_LE((top4.col(i) - full.col(i)).norm(), dropped * spread + 1e-12) << i;
      }
    }
  }
  std::printf(
      "10 bones, %d vertices: bones move vertices by up to %.4f; max vertex error: glTF (spec "
      "evaluator) vs top-4 LBS %.3g, synth rig loader vs top-4 LBS %.3g, top-4 truncation %.3g, "
      "glTF vs ArticulateMesh %.3g (max dropped weight %.4f)\n",
      canonical.NumVertices(), skinning_motion, export_error, rig_error, truncation_error,
      total_error, summary.max_dropped_weight);
  EXPECT_GT(skinning_motion, 0.05);  // the skinning is really exercised
  EXPECT_LT(export_error, kFloatTolerance);
  EXPECT_LT(rig_error, kFloatTolerance);
  EXPECT_GT(truncation_error, 0.0);  // > 4 bones with overlapping Gaussians
  EXPECT_GT(summary.max_dropped_weight, 0.0);
  EXPECT_LE(total_error, truncation_error + kFloatTolerance);
}

// With <= 4 bones nothing is truncated: the export equals ArticulateMesh up
// to float rounding, also between the bind pose and the rest pose.
TEST_F(GltfExport, ExactWithFourBonesOrFewer) {
  const auto model = MakeExportTestModel(3, 11);
  const fs::path path = dir_ / "three.glb";
  const GltfExportSummary summary = ExportGltf(*model, options_, path.string());
  EXPECT_EQ(summary.max_dropped_weight, 0.0);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  tinygltf::Model gltf;
  ReadGltf(path.string(), &gltf);
  for (int v = 0; v < 2; ++v) {
    for (int t = 0; t < static_cast<int>(model->video(v).frames.size()); ++t) {
      const Eigen::Matrix3Xd posed =
          GltfToOpenCv(SpecPosedPositions(gltf, v, testing::KeyTime(t, options_.fps)));
      EXPECT_LT(MaxVertexError(posed, ArticulateMesh(*model, canonical, v, t).vertices),
                kFloatTolerance)
          << v << ":" << t;
    }
  }
  // Rest pose of the hierarchy (no animation) = bind pose = canonical mesh.
  EXPECT_LT(MaxVertexError(GltfToOpenCv(SpecPosedPositions(gltf, -1, 0)), canonical.vertices),
            kFloatTolerance);
}

// Sharp bones: most vertices have one bone and weights that underflow to 0
// for the others; a slot of weight 0 names joint 0 (the Khronos validator
// warns about a zero weight with another joint, ACCESSOR_JOINTS_USED_ZERO_WEIGHT).
TEST_F(GltfExport, ZeroWeightSlotsNameJointZero) {
  const auto model = MakeExportTestModel(8, 5);
  for (int b = 0; b < model->num_bones(); ++b) {
    for (int k = 0; k < 3; ++k) model->bones()[kBoneSize * b + kBoneLogScale + k] = std::log(0.004);
  }
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  ASSERT_GT(canonical.NumVertices(), 0);
  tinygltf::Model gltf;
  BuildGltf(*model, canonical, options_, &gltf);
  const tinygltf::Primitive& prim = gltf.meshes[0].primitives[0];
  const Eigen::MatrixXd joints = testing::ReadAccessor(gltf, prim.attributes.at("JOINTS_0"));
  const Eigen::MatrixXd weights = testing::ReadAccessor(gltf, prim.attributes.at("WEIGHTS_0"));
  ASSERT_EQ(joints.size(), weights.size());
  int zero_slots = 0;
  for (Eigen::Index i = 0; i < weights.size(); ++i) {
    if (weights(i) != 0.0) continue;
    ++zero_slots;
    EXPECT_EQ(joints(i), 0.0) << "slot " << i;
  }
  EXPECT_GT(zero_slots, canonical.NumVertices());  // the case is exercised
}

// The forward delta-skinning logits use the rest-pose code, so the forward
// weights do not depend on the frame and the export stays exact (3 bones: no
// truncation).
TEST_F(GltfExport, ExactWithForwardDeltaSkinning) {
  const auto model = MakeExportTestModel(3, 13, /*delta_skinning=*/true);
  ASSERT_TRUE(model->DeltaSkinningIsNonZero());
  const fs::path path = dir_ / "delta.glb";
  ExportGltf(*model, options_, path.string());
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  // The delta logits really change the weights.
  EXPECT_GT(ForwardDeltaLogits(*model, canonical.vertices).cwiseAbs().maxCoeff(), 0.1);
  tinygltf::Model gltf;
  ReadGltf(path.string(), &gltf);
  for (int v = 0; v < 2; ++v) {
    for (int t = 0; t < static_cast<int>(model->video(v).frames.size()); ++t) {
      const Eigen::Matrix3Xd posed =
          GltfToOpenCv(SpecPosedPositions(gltf, v, testing::KeyTime(t, options_.fps)));
      EXPECT_LT(MaxVertexError(posed, ArticulateMesh(*model, canonical, v, t).vertices),
                kFloatTolerance)
          << v << ":" << t;
    }
  }
}

TEST_F(GltfExport, RigidModelHasRootAnimationOnly) {
  const auto model = MakeExportTestModel(0, 3);
  const fs::path path = dir_ / "rigid.glb";
  const GltfExportSummary summary = ExportGltf(*model, options_, path.string());
  EXPECT_EQ(summary.joints, 0);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  tinygltf::Model gltf;
  ReadGltf(path.string(), &gltf);
  EXPECT_TRUE(gltf.skins.empty());
  EXPECT_EQ(gltf.meshes[0].primitives[0].attributes.count("JOINTS_0"), 0u);
  for (const tinygltf::Animation& a : gltf.animations) EXPECT_EQ(a.channels.size(), 2u);
  const Eigen::Matrix3Xd posed =
      GltfToOpenCv(SpecPosedPositions(gltf, 1, testing::KeyTime(3, options_.fps)));
  EXPECT_LT(MaxVertexError(posed, ArticulateMesh(*model, canonical, 1, 3).vertices),
            kFloatTolerance);
}

// The file is in dataset units: with scene scale s every posed frame and
// the bind pose are s times the model's (ArticulateMesh, model units), for
// a skinned and a rigid model and for a tiny and a huge s.
TEST_F(GltfExport, FileIsInDatasetUnits) {
  for (const int bones : {3, 0}) {
    for (const double s : {1.0 / 128, 100.0}) {
      SCOPED_TRACE("bones " + std::to_string(bones) + ", s " + std::to_string(s));
      const auto model = MakeExportTestModel(bones, 17);
      model->set_scene_scale(s);
      const fs::path path = dir_ / "scaled.glb";
      ExportGltf(*model, options_, path.string());
      const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
      tinygltf::Model gltf;
      ReadGltf(path.string(), &gltf);
      // Divided by s, the float32 file carries the same relative rounding as
      // at s = 1 (kFloatTolerance).
      const Eigen::Matrix3Xd rest = GltfToOpenCv(SpecPosedPositions(gltf, -1, 0)) / s;
      EXPECT_LT(MaxVertexError(rest, canonical.vertices), kFloatTolerance);
      for (int t = 0; t < 4; ++t) {
        const Eigen::Matrix3Xd posed =
            GltfToOpenCv(SpecPosedPositions(gltf, 1, testing::KeyTime(t, options_.fps))) / s;
        EXPECT_LT(MaxVertexError(posed, ArticulateMesh(*model, canonical, 1, t).vertices),
                  kFloatTolerance)
            << t;
      }
    }
  }
}

// LINEAR equals the model at keys and interpolates between them; STEP holds
// the previous key. Also: .gltf output with an embedded buffer, custom names.
TEST_F(GltfExport, InterpolationGltfTextAndNames) {
  const auto model = MakeExportTestModel(6, 5);
  options_.video_names = {"walk", "run"};
  options_.fps = 24;
  const fs::path linear = dir_ / "linear.gltf";
  ExportGltf(*model, options_, linear.string());
  options_.interpolation = GltfInterpolation::kStep;
  const fs::path step = dir_ / "step.glb";
  ExportGltf(*model, options_, step.string());

  // .gltf is JSON with the buffer as a data URI (one file).
  std::FILE* f = std::fopen(linear.c_str(), "rb");
  ASSERT_NE(f, nullptr);
  char head[2] = {0, 0};
  ASSERT_EQ(std::fread(head, 1, 1, f), 1u);
  std::fclose(f);
  EXPECT_EQ(head[0], '{');
  tinygltf::Model a, b;
  ReadGltf(linear.string(), &a);
  ReadGltf(step.string(), &b);
  EXPECT_EQ(a.buffers.size(), 1u);
  EXPECT_EQ(a.animations[1].name, "run");
  EXPECT_EQ(a.animations[0].samplers[0].interpolation, "LINEAR");
  EXPECT_EQ(b.animations[0].samplers[0].interpolation, "STEP");

  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  const double t1 = testing::KeyTime(1, options_.fps), t2 = testing::KeyTime(2, options_.fps);
  const Eigen::Matrix3Xd k1 = ArticulateMesh(*model, canonical, 1, 1).vertices;
  const Eigen::Matrix3Xd k2 = ArticulateMesh(*model, canonical, 1, 2).vertices;
  // At keys both agree (to truncation + float; 6 bones).
  const double at_key = MaxVertexError(GltfToOpenCv(SpecPosedPositions(a, 1, t2)),
                                       GltfToOpenCv(SpecPosedPositions(b, 1, t2)));
  EXPECT_LT(at_key, kFloatTolerance);
  // Between keys, STEP holds key 1 exactly; LINEAR lies between the keys:
  // closer to each end than the keys are to each other.
  const double mid = 0.5 * (t1 + t2);
  const Eigen::Matrix3Xd step_mid = GltfToOpenCv(SpecPosedPositions(b, 1, mid));
  const Eigen::Matrix3Xd step_k1 = GltfToOpenCv(SpecPosedPositions(b, 1, t1));
  EXPECT_LT(MaxVertexError(step_mid, step_k1), kFloatTolerance);
  const Eigen::Matrix3Xd lin_mid = GltfToOpenCv(SpecPosedPositions(a, 1, mid));
  const double keys_apart = MaxVertexError(k1, k2);
  EXPECT_GT(keys_apart, 0.05);
  EXPECT_LT(MaxVertexError(lin_mid, k1), keys_apart);
  EXPECT_LT(MaxVertexError(lin_mid, k2), keys_apart);
}

// Colours: COLOR_0 holds (c / 255)^2.2; the synth loader reads them back as
// display values with gamma 1/2.2.
TEST_F(GltfExport, VertexColoursRoundTrip) {
  const auto model = MakeExportTestModel(2, 9);
  const fs::path path = dir_ / "colours.glb";
  ExportGltf(*model, options_, path.string());
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options_.extract);
  ASSERT_TRUE(canonical.HasColors());
  const synth::Rig rig = synth::LoadGltfRig(path.string());
  ASSERT_EQ(rig.vertex_colors.cols(), canonical.NumVertices());
  // uint8 -> float linear -> display: within float rounding of c / 255.
  const Eigen::MatrixXd expected = canonical.colors.cast<double>() / 255.0;
  EXPECT_LT((rig.vertex_colors.cast<double>() - expected).cwiseAbs().maxCoeff(), 1e-5);
}

TEST_F(GltfExport, NonFiniteModelIsAnErrorAndWritesNothing) {
  const auto model = MakeExportTestModel(5, 2);
  model->frame(1, 2).bones_t[kPoseSize * 3 + 5] = std::nan("");
  const fs::path path = dir_ / "bad.glb";
  try {
    ExportGltf(*model, options_, path.string());
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("video 1 frame 2"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(GltfExport, UnwritablePathIsAnInputError) {
  const auto model = MakeExportTestModel(2, 2);
  const std::string path = (dir_ / "missing_folder" / "x.glb").string();
  EXPECT_THROW(ExportGltf(*model, options_, path), InputError);
  EXPECT_FALSE(fs::exists(path));
}

// ---- The validator on hand-broken documents ----

class GltfValidate : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = MakeExportTestModel(6, 4);
    GltfExportOptions o;
    o.extract.grid.resolution = 24;
    canonical_ = ExtractCanonicalMesh(*model_, o.extract);
    BuildGltf(*model_, canonical_, o, &gltf_);
    ASSERT_TRUE(ValidateGltf(gltf_).empty());
  }

  // Pointer to element `i`, component `c` of accessor `index` (tightly packed).
  template <typename T>
  T* Element(int index, int i, int c) {
    const tinygltf::Accessor& a = gltf_.accessors[index];
    const tinygltf::BufferView& v = gltf_.bufferViews[a.bufferView];
    const int comps = tinygltf::GetNumComponentsInType(a.type);
    return reinterpret_cast<T*>(gltf_.buffers[v.buffer].data.data() + v.byteOffset + a.byteOffset) +
           static_cast<size_t>(i) * comps + c;
  }
  int Attribute(const char* name) { return gltf_.meshes[0].primitives[0].attributes.at(name); }

  // Expects exactly the problems to contain `text`, and CheckGltfOrThrow to throw.
  void ExpectProblem(const std::string& text) {
    const std::vector<std::string> problems = ValidateGltf(gltf_);
    ASSERT_FALSE(problems.empty()) << "expected: " << text;
    bool found = false;
    for (const std::string& p : problems) found = found || p.find(text) != std::string::npos;
    EXPECT_TRUE(found) << "expected '" << text << "', got: " << problems[0];
    EXPECT_THROW(CheckGltfOrThrow(gltf_, "test.glb"), InputError);
  }

  std::unique_ptr<Model> model_;
  TriangleMesh canonical_;
  tinygltf::Model gltf_;
};

TEST_F(GltfValidate, WeightsNotSummingToOne) {
  *Element<float>(Attribute("WEIGHTS_0"), 17, 0) *= 0.99f;
  ExpectProblem("WEIGHTS_0 vertex 17: weights sum to");
}

TEST_F(GltfValidate, NegativeWeight) {
  float* w = Element<float>(Attribute("WEIGHTS_0"), 3, 0);
  w[1] += w[3] + 0.5f;  // sum stays 1 after the next line
  w[3] = -0.5f;
  ExpectProblem("negative weight");
}

TEST_F(GltfValidate, JointIndexOutOfRange) {
  *Element<uint16_t>(Attribute("JOINTS_0"), 5, 2) = 6;  // 6 joints: 0..5
  ExpectProblem("JOINTS_0 vertex 5: joint 6 >= skin joint count 6");
}

TEST_F(GltfValidate, WrongPositionBounds) {
  gltf_.accessors[Attribute("POSITION")].maxValues[1] += 1e-3;
  ExpectProblem("POSITION: min/max");
  gltf_.accessors[Attribute("POSITION")].maxValues.clear();
  ExpectProblem("min/max missing");
}

TEST_F(GltfValidate, PositionOutOfBoundsAfterEdit) {
  *Element<float>(Attribute("POSITION"), 0, 2) = 5.0f;  // outside the stored max
  ExpectProblem("POSITION: min/max");
}

TEST_F(GltfValidate, InverseBindMatrixCount) {
  gltf_.accessors[gltf_.skins[0].inverseBindMatrices].count -= 1;
  ExpectProblem("5 matrices for 6 joints");
}

TEST_F(GltfValidate, TimesNotIncreasing) {
  const int input = gltf_.animations[1].samplers[0].input;
  *Element<float>(input, 2, 0) = *Element<float>(input, 1, 0);
  ExpectProblem("not strictly increasing");
}

TEST_F(GltfValidate, NonUnitQuaternion) {
  const tinygltf::AnimationChannel& c = gltf_.animations[0].channels[3];
  ASSERT_EQ(c.target_path, "rotation");
  for (int k = 0; k < 4; ++k)
    *Element<float>(gltf_.animations[0].samplers[c.sampler].output, 1, k) *= 1.01f;
  ExpectProblem("not a unit quaternion");
}

TEST_F(GltfValidate, IndexBeyondVertices) {
  *Element<uint32_t>(gltf_.meshes[0].primitives[0].indices, 4, 0) =
      static_cast<uint32_t>(canonical_.NumVertices());
  ExpectProblem("indices: index");
}

TEST_F(GltfValidate, AccessorBeyondItsView) {
  gltf_.accessors[Attribute("NORMAL")].count += 1;
  ExpectProblem("do not fit");
}

TEST_F(GltfValidate, NodeCycle) {
  gltf_.nodes[2].children.push_back(0);  // bone_0 -> opencv_to_gltf -> root -> bone_0
  ExpectProblem("cycle");
}

// The shared Fox glTF (a third-party file, uint8-normalised weights in some
// exports) passes with a tolerance suited to its encoding.
TEST(GltfValidateShared, FoxPasses) {
  const std::string path = testing::SharedAsset("data/gltf/Fox/Fox.glb");
  ASSERT_TRUE(testing::SharedAssetExists(path));
  tinygltf::Model fox;
  ReadGltf(path, &fox);
  GltfValidationOptions o;
  o.weight_sum_tolerance = 1e-2;
  const std::vector<std::string> problems = ValidateGltf(fox, o);
  EXPECT_TRUE(problems.empty()) << problems[0];
}

}  // namespace
}  // namespace banmo

namespace banmo {
namespace {

// Measurement on a real checkpoint (docs/export.md), skipped unless
//   BANMO_GLTF_MEASURE_MODEL=<checkpoint folder> and
//   BANMO_GLTF_MEASURE_GLB=<file written by banmo export from it>
//   BANMO_GLTF_MEASURE_RESOLUTION=<its --resolution> (default 128)
// are set: every key frame of every video posed with the spec evaluator,
// against top-4 LBS in double and ArticulateMesh.
TEST(GltfExportMeasure, CheckpointFromEnvironment) {
  const char* model_dir = std::getenv("BANMO_GLTF_MEASURE_MODEL");
  const char* glb = std::getenv("BANMO_GLTF_MEASURE_GLB");
  if (model_dir == nullptr || glb == nullptr) GTEST_SKIP() << "measurement variables not set";
  const char* res = std::getenv("BANMO_GLTF_MEASURE_RESOLUTION");
  const auto model = LoadCheckpoint(model_dir);
  ExtractOptions e;
  e.grid.resolution = res != nullptr ? std::atoi(res) : 128;
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, e);
  tinygltf::Model gltf;
  ReadGltf(glb, &gltf);
  ASSERT_TRUE(ValidateGltf(gltf).empty());
  const double fps = [&] {
    const Eigen::MatrixXd t = testing::ReadAccessor(gltf, gltf.animations[0].samplers[0].input);
    return 1.0 / t(0, 1);  // keys at t / fps
  }();
  double export_error = 0, truncation_error = 0, total_error = 0, extent = 0;
  int frames = 0;
  for (int v = 0; v < model->num_videos(); ++v) {
    for (int t = 0; t < static_cast<int>(model->video(v).frames.size()); ++t) {
      const Eigen::Matrix3Xd posed =
          GltfToOpenCv(SpecPosedPositions(gltf, v, testing::KeyTime(t, fps)));
      ASSERT_EQ(posed.cols(), canonical.NumVertices());
      const Eigen::Matrix3Xd full = ArticulateMesh(*model, canonical, v, t).vertices;
      const Eigen::Matrix3Xd top4 = TopKLbs(*model, canonical, v, t);
      export_error = std::max(export_error, MaxVertexError(posed, top4));
      truncation_error = std::max(truncation_error, MaxVertexError(top4, full));
      total_error = std::max(total_error, MaxVertexError(posed, full));
      extent = std::max(extent, (full.rowwise().maxCoeff() - full.rowwise().minCoeff()).norm());
      ++frames;
    }
  }
  std::printf(
      "%s: %d vertices, %d frames, mesh diagonal up to %.4f: max vertex error glTF vs top-4 LBS "
      "%.3g, top-4 truncation %.3g, glTF vs ArticulateMesh %.3g\n",
      model_dir, canonical.NumVertices(), frames, extent, export_error, truncation_error,
      total_error);
  EXPECT_LT(export_error, kFloatTolerance);
}

}  // namespace
}  // namespace banmo
