#include "banmo/extract/extract.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "banmo/geometry/mesh_io.h"
#include "banmo/io/npy.h"
#include "banmo/util/error.h"
#include "mesh_test_util.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing_util::CountNonManifoldVertices;
using testing_util::WindingNumber;

constexpr double kRadius = 0.5;

// A model straight after initialisation: the SDF MLP (width 64, 3 layers)
// is the geometric-init sphere |X| - 0.5; two videos of 3 and 2 frames.
std::unique_ptr<Model> SphereModel(int num_bones = 4) {
  ModelOptions options;
  options.field.sdf_width = 64;
  options.field.init_sphere_radius = kRadius;
  options.num_bones = num_bones;
  PinholeCamera camera;
  camera.width = camera.height = 64;
  camera.intrinsics = Eigen::Vector4d(60, 60, 32, 32);
  return std::make_unique<Model>(options, std::vector<int>{3, 2},
                                 std::vector<PinholeCamera>{camera, camera});
}

ExtractOptions Quick(int resolution = 48) {
  ExtractOptions o;
  o.grid.resolution = resolution;
  return o;
}

std::string TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("banmo_extract_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir.string();
}

TEST(ExtractCanonicalMesh, InitialSphereIsClosedRoundAndOutward) {
  const auto model = SphereModel();
  const ExtractOptions options = Quick(64);
  const TriangleMesh mesh = ExtractCanonicalMesh(*model, options);
  ASSERT_GT(mesh.NumFaces(), 1000);
  const MeshStats s = ComputeMeshStats(mesh);
  EXPECT_TRUE(s.IsClosedOriented());
  EXPECT_EQ(CountNonManifoldVertices(mesh), 0);
  EXPECT_EQ(s.num_components, 1);
  EXPECT_EQ(s.euler_characteristic, 2);
  // The geometric initialisation is refitted to |X| - r with mean error
  // 0.017 and max 0.10 over the ball of radius 1.5 (canonical_field.h); on
  // the sphere itself the measured vertex radius error is 0.032 max and
  // 0.0099 mean (resolution 48 and 64 alike: the field's error, not the
  // grid's). Tolerances: 0.05 max, 0.015 mean.
  double max_error = 0.0, mean_error = 0.0;
  for (int i = 0; i < mesh.NumVertices(); ++i) {
    const double e = std::abs(mesh.vertices.col(i).norm() - kRadius);
    max_error = std::max(max_error, e);
    mean_error += e / mesh.NumVertices();
  }
  EXPECT_LT(max_error, 0.05);
  EXPECT_LT(mean_error, 0.015);
  const double volume = 4.0 / 3.0 * M_PI * std::pow(kRadius, 3);
  // Measured -5.1 % (about 3 x the field's mean radius error, relative).
  EXPECT_NEAR(s.signed_volume, volume, 0.08 * volume);
  ASSERT_TRUE(mesh.HasColors());
  // Outward: the winding number is 1 at the centre and 0 outside.
  EXPECT_NEAR(WindingNumber(mesh, Eigen::Vector3d::Zero()), 1.0, 1e-9);
  EXPECT_NEAR(WindingNumber(mesh, Eigen::Vector3d(0.9, 0, 0)), 0.0, 1e-9);
}

TEST(ExtractCanonicalMesh, CoarseToFineEqualsDenseOnTheMlp) {
  const auto model = SphereModel();
  ExtractOptions dense = Quick(64);
  dense.grid.coarse_stride = 1;
  ExtractOptions coarse = Quick(64);
  coarse.grid.coarse_stride = 4;
  const TriangleMesh a = ExtractCanonicalMesh(*model, dense);
  const TriangleMesh b = ExtractCanonicalMesh(*model, coarse);
  ASSERT_EQ(a.NumVertices(), b.NumVertices());
  ASSERT_EQ(a.NumFaces(), b.NumFaces());
  // The same nodes are evaluated, in batches of other sizes: equal up to
  // rounding of the batched matrix products.
  EXPECT_LT((a.vertices - b.vertices).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE((a.faces.array() == b.faces.array()).all());
}

TEST(ExtractCanonicalMesh, ColorsMatchTheColourMlp) {
  const auto model = SphereModel();
  ExtractOptions options = Quick(24);
  options.color_video = 1;
  model->video(1).appearance = {0.5, -1.0, 2.0, 0.1};
  const TriangleMesh mesh = ExtractCanonicalMesh(*model, options);
  ASSERT_TRUE(mesh.HasColors());
  for (int i = 0; i < mesh.NumVertices(); i += 37) {
    const Eigen::Vector3d x = mesh.vertices.col(i);
    const Eigen::Vector3d view(0, 0, 1);
    double sdf, rgb[3];
    model->field().Evaluate(model->sdf(), model->color(), x.data(), view.data(),
                            model->video(1).appearance.data(), &sdf, rgb);
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(mesh.colors(c, i), static_cast<int>(std::lround(255 * rgb[c]))) << i;
    }
  }
}

TEST(ArticulateMesh, IdentityBonesAndRootGiveTheCanonicalMesh) {
  const auto model = SphereModel();
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, Quick(24));
  const TriangleMesh posed = ArticulateMesh(*model, canonical, 1, 1);
  ASSERT_EQ(posed.NumVertices(), canonical.NumVertices());
  EXPECT_LT((posed.vertices - canonical.vertices).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE((posed.faces.array() == canonical.faces.array()).all());
}

TEST(ArticulateMesh, SharedBoneTransformIsARigidMotion) {
  auto model = SphereModel(5);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, Quick(24));
  const Pose bone =
      PoseFromAngleAxis(Eigen::Vector3d(0.3, -0.2, 0.5), Eigen::Vector3d(0.1, 0.2, -0.1));
  const Pose root_delta =
      PoseFromAngleAxis(Eigen::Vector3d(0.0, 0.4, 0.0), Eigen::Vector3d(0, 0, 0.5));
  const Pose root_init =
      PoseFromAngleAxis(Eigen::Vector3d(-0.1, 0.0, 0.2), Eigen::Vector3d(0.1, 0, 3));
  FrameParameters& f = model->frame(0, 2);
  for (int b = 0; b < model->num_bones(); ++b) {
    std::copy(bone.data(), bone.data() + kPoseSize, f.bones_t.data() + kPoseSize * b);
  }
  f.root_delta = root_delta;
  f.root_init = root_init;
  const Eigen::Isometry3d expected = IsometryFromPose(root_init.data()) *
                                     IsometryFromPose(root_delta.data()) *
                                     IsometryFromPose(bone.data());
  const TriangleMesh posed = ArticulateMesh(*model, canonical, 0, 2);
  // The blend of B equal points is that point up to rounding (1e-15 relative).
  const Eigen::Matrix3Xd want = expected * canonical.vertices;
  EXPECT_LT((posed.vertices - want).cwiseAbs().maxCoeff(), 1e-12);
  // Other frames are untouched.
  EXPECT_LT(
      (ArticulateMesh(*model, canonical, 0, 1).vertices - canonical.vertices).cwiseAbs().maxCoeff(),
      1e-12);
  EXPECT_THROW(ArticulateMesh(*model, canonical, 2, 0), InputError);
  EXPECT_THROW(ArticulateMesh(*model, canonical, 1, 2), InputError);
}

TEST(ArticulateMesh, DifferentBonesBendTheMesh) {
  // One bone moved: the vertices near it follow it, the far ones stay.
  auto model = SphereModel(2);
  std::vector<Eigen::Vector3d> centres = {{-0.4, 0, 0}, {0.4, 0, 0}};
  InitializeBones(centres, 0.2, model->bones());
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, Quick(24));
  const Pose lift = PoseFromAngleAxis(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0.3, 0));
  std::copy(lift.data(), lift.data() + kPoseSize, model->frame(0, 0).bones_t.data() + kPoseSize);
  const TriangleMesh posed = ArticulateMesh(*model, canonical, 0, 0);
  for (int i = 0; i < canonical.NumVertices(); ++i) {
    const double x = canonical.vertices(0, i);
    const double dy = posed.vertices(1, i) - canonical.vertices(1, i);
    if (x > 0.3) {
      EXPECT_NEAR(dy, 0.3, 1e-3);
    }
    if (x < -0.3) {
      EXPECT_NEAR(dy, 0.0, 1e-3);
    }
  }
}

// With a non-zero MLP_Delta, ArticulateMesh and SkinningWeightsAt add the
// forward delta logits (rest-pose code) exactly as the templated warp does.
TEST(ArticulateMesh, DeltaSkinningLogitsEnterTheForwardWarp) {
  ModelOptions options;
  options.field.sdf_width = 64;
  options.field.init_sphere_radius = kRadius;
  options.num_bones = 3;
  options.delta_skinning.enabled = true;
  options.delta_skinning.width = 8;
  options.delta_skinning.pose_code_dim = 2;
  PinholeCamera camera;
  camera.width = camera.height = 64;
  camera.intrinsics = Eigen::Vector4d(60, 60, 32, 32);
  Model model(options, {2}, {camera});
  const TriangleMesh canonical = ExtractCanonicalMesh(model, Quick(16));
  // Without delta logits the weights are the Gaussian ones.
  EXPECT_EQ(ForwardDeltaLogits(model, canonical.vertices).rows(), 0);
  const Eigen::MatrixXd gaussian = SkinningWeightsAt(model, canonical.vertices);
  for (int k = 0; k < model.delta_skinning_size(); ++k) {
    model.delta_skinning_params()[k] = 0.5 * std::sin(1.7 * k + 0.3);
  }
  ASSERT_TRUE(model.DeltaSkinningIsNonZero());
  for (int b = 0; b < 3; ++b) {
    const Pose j = PoseFromAngleAxis(Eigen::Vector3d(0.2 * b, -0.1, 0.3),
                                     Eigen::Vector3d(0.05 * b, 0.1, -0.05));
    std::copy(j.data(), j.data() + kPoseSize, model.frame(0, 1).bones_t.data() + kPoseSize * b);
  }
  const TriangleMesh posed = ArticulateMesh(model, canonical, 0, 1);
  const Eigen::MatrixXd weights = SkinningWeightsAt(model, canonical.vertices);
  const Pose camera_from_root = model.RootPose(0, 1);
  double weight_change = 0.0;
  for (int i = 0; i < canonical.NumVertices(); ++i) {
    double delta[3], x_root[3], expected[3], logits[3], w[3];
    model.delta_skinning()->Logits(model.delta_skinning_params(), canonical.vertices.col(i).data(),
                                   model.rest_pose_code(), delta);
    ForwardWarp(3, model.bones(), model.frame(0, 1).bones_t.data(),
                canonical.vertices.col(i).data(), x_root, delta);
    PoseTransformPoint(camera_from_root.data(), x_root, expected);
    // Batched MLP against the single-point path: same arithmetic up to GEMM
    // order (1e-12 on unit-size coordinates).
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(posed.vertices(c, i), expected[c], 1e-12);
    for (int b = 0; b < 3; ++b) {
      logits[b] =
          BoneLogit(model.bones() + kBoneSize * b, canonical.vertices.col(i).data()) + delta[b];
    }
    SkinningWeights(3, logits, w);
    for (int b = 0; b < 3; ++b) {
      EXPECT_NEAR(weights(b, i), w[b], 1e-12);
      weight_change = std::max(weight_change, std::abs(weights(b, i) - gaussian(b, i)));
    }
  }
  EXPECT_GT(weight_change, 1e-3);  // the delta logits matter
}

TEST(Skinning, WeightsBonesAndDominantColours) {
  auto model = SphereModel(3);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, Quick(24));
  const Eigen::MatrixXd w = SkinningWeightsAt(*model, canonical.vertices);
  ASSERT_EQ(w.rows(), 3);
  ASSERT_EQ(w.cols(), canonical.NumVertices());
  EXPECT_LT((w.colwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
  EXPECT_GE(w.minCoeff(), 0.0);
  const TriangleMesh colored = ColorByDominantBone(canonical, w);
  for (int i = 0; i < canonical.NumVertices(); ++i) {
    Eigen::Index b;
    w.col(i).maxCoeff(&b);
    ASSERT_EQ(colored.colors.col(i), BonePaletteColor(static_cast<int>(b)));
  }
  // Ellipsoids: B closed, outward, genus-0 components with the Gaussian's
  // volume (4/3 pi prod(sigma s_k)) up to the icosphere's inscribed-volume
  // deficit (measured -3.4 % at 2 subdivisions).
  const TriangleMesh ellipsoids = BoneEllipsoids(*model, 2.0, 2);
  const MeshStats s = ComputeMeshStats(ellipsoids);
  EXPECT_TRUE(s.IsClosedOriented());
  EXPECT_EQ(s.num_components, 3);
  EXPECT_EQ(s.euler_characteristic, 6);
  double volume = 0.0;
  for (int b = 0; b < 3; ++b) {
    const double* lb = model->bones() + kBoneSize * b + kBoneLogScale;
    volume += 4.0 / 3.0 * M_PI * 8.0 * std::exp(lb[0] + lb[1] + lb[2]);
  }
  EXPECT_NEAR(s.signed_volume, 0.966 * volume, 0.005 * volume);
  // Distinct palette colours for the first bones.
  EXPECT_NE(BonePaletteColor(0), BonePaletteColor(1));
  EXPECT_NE(BonePaletteColor(12), BonePaletteColor(13));
  // No bones: empty outputs.
  auto rigid = SphereModel(0);
  EXPECT_EQ(SkinningWeightsAt(*rigid, canonical.vertices).rows(), 0);
  EXPECT_EQ(BoneEllipsoids(*rigid, 1.0, 1).NumFaces(), 0);
}

TEST(SurfaceBounds, CoarseBoundsOfTheSphere) {
  const auto model = SphereModel();
  const Eigen::AlignedBox3d box = SurfaceBounds(
      *model, Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1)), 48);
  ASSERT_FALSE(box.isEmpty());
  // Within the field's radius error (0.05, above) of [-r, r]^3.
  EXPECT_LT((box.min() + Eigen::Vector3d::Constant(kRadius)).cwiseAbs().maxCoeff(), 0.05);
  EXPECT_LT((box.max() - Eigen::Vector3d::Constant(kRadius)).cwiseAbs().maxCoeff(), 0.05);
  const Eigen::AlignedBox3d none = SurfaceBounds(
      *model, Eigen::AlignedBox3d(Eigen::Vector3d::Constant(0.8), Eigen::Vector3d::Constant(1)), 8);
  EXPECT_TRUE(none.isEmpty());
}

// The extraction box is the box training sampled (stored with the model),
// [-1, 1]^3 only for a model without one; an object reaching beyond the unit
// cube is no longer cut at its faces.
TEST(ExtractionBounds, TheTrainedBoxWhenTheModelHasOne) {
  const auto model = SphereModel();
  const Eigen::AlignedBox3d unit(Eigen::Vector3d::Constant(-1), Eigen::Vector3d::Constant(1));
  EXPECT_TRUE(ExtractionBounds(*model).isApprox(unit));
  const Eigen::AlignedBox3d trained(Eigen::Vector3d(-1.4, -0.6, -0.3),
                                    Eigen::Vector3d(1.2, 0.7, 0.45));
  model->set_canonical_bounds(trained);
  EXPECT_TRUE(ExtractionBounds(*model).isApprox(trained));
  // A flat box is a programming error (the model file refuses one and the
  // solver never sets one), not a silent fallback to the unit cube.
  model->set_canonical_bounds(
      Eigen::AlignedBox3d(Eigen::Vector3d::Constant(0.5), Eigen::Vector3d(0.5, 1, 1)));
  EXPECT_DEATH(ExtractionBounds(*model), "not a valid box");
}

TEST(ParseFrameSelection, FormsAndErrors) {
  const auto model = SphereModel();
  EXPECT_TRUE(ParseFrameSelection("all", *model).all);
  const FrameSelection none = ParseFrameSelection("none", *model);
  EXPECT_FALSE(none.all);
  EXPECT_TRUE(none.frames.empty());
  const FrameSelection s = ParseFrameSelection("0:1,1:*,0:0-2", *model);
  EXPECT_FALSE(s.all);
  const std::vector<std::pair<int, int>> want = {{0, 1}, {1, 0}, {1, 1}, {0, 0}, {0, 1}, {0, 2}};
  EXPECT_EQ(s.frames, want);
  for (const char* bad : {"", "3", "2:0", "0:3", "0:2-1", "0:x", "a:1", "0:-1", "1:0-5", "0:1,"}) {
    try {
      ParseFrameSelection(bad, *model, "--frames");
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--frames"), std::string::npos) << e.what();
    }
  }
}

TEST(WriteExtraction, WritesAllFilesReadableByTheReaders) {
  auto model = SphereModel(3);
  const std::string dir = TempDir("write");
  ExtractOptions options = Quick(24);
  const ExtractionSummary summary = WriteExtraction(*model, options, dir);
  EXPECT_EQ(summary.frames_written, 5);
  const TriangleMesh canonical = ReadMesh(dir + "/canonical.ply");
  EXPECT_EQ(canonical.NumVertices(), summary.canonical_vertices);
  EXPECT_EQ(canonical.NumFaces(), summary.canonical_faces);
  EXPECT_TRUE(canonical.HasColors());
  EXPECT_EQ(ReadMesh(dir + "/skinning.ply").NumVertices(), canonical.NumVertices());
  EXPECT_EQ(ReadMesh(dir + "/bones.ply").NumFaces(), 3 * 320);
  const cv::Mat w = ReadNpy(dir + "/skinning_weights.npy");
  ASSERT_EQ(w.rows, canonical.NumVertices());
  ASSERT_EQ(w.cols, 3);
  ASSERT_EQ(w.type(), CV_32FC1);
  const Eigen::MatrixXd expect = SkinningWeightsAt(*model, canonical.vertices);
  for (int i = 0; i < w.rows; i += 11) {
    for (int b = 0; b < 3; ++b) EXPECT_NEAR(w.at<float>(i, b), expect(b, i), 1e-6);
  }
  // The embedding of every vertex, as the field evaluates it (float32).
  const cv::Mat psi = ReadNpy(dir + "/embedding.npy");
  ASSERT_EQ(psi.rows, canonical.NumVertices());
  ASSERT_EQ(psi.cols, CanonicalField::EmbeddingDim());
  ASSERT_EQ(psi.type(), CV_32FC1);
  double spread = 0.0;
  for (int i = 0; i < psi.rows; i += 7) {
    double expect[CanonicalField::EmbeddingDim()];
    model->field().EvaluateEmbedding(model->embedding(), canonical.vertices.col(i).data(), expect);
    for (int c = 0; c < psi.cols; ++c) {
      EXPECT_NEAR(psi.at<float>(i, c), expect[c], 1e-6 * (1.0 + std::abs(expect[c])));
      spread += std::abs(expect[c] - psi.at<float>(0, c));
    }
  }
  EXPECT_GT(spread, 0.0);  // not one value for all vertices
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir + "/frames")) {
    names.push_back(e.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  const std::vector<std::string> want = {"video00_frame00000.ply", "video00_frame00001.ply",
                                         "video00_frame00002.ply", "video01_frame00000.ply",
                                         "video01_frame00001.ply"};
  EXPECT_EQ(names, want);
  EXPECT_TRUE(fs::exists(dir + "/extract.json"));
  fs::remove_all(dir);

  // A selection, and a rigid model (no bone files).
  auto rigid = SphereModel(0);
  options.frames = ParseFrameSelection("1:1", *rigid);
  WriteExtraction(*rigid, options, dir);
  EXPECT_TRUE(fs::exists(dir + "/frames/video01_frame00001.ply"));
  EXPECT_FALSE(fs::exists(dir + "/frames/video00_frame00000.ply"));
  EXPECT_FALSE(fs::exists(dir + "/bones.ply"));
  EXPECT_FALSE(fs::exists(dir + "/skinning_weights.npy"));
  EXPECT_TRUE(fs::exists(dir + "/embedding.npy"));
  fs::remove_all(dir);
}

// The files are in dataset units: the model's meshes times its scene scale
// (exact: PLY stores doubles and the scale is a power of two here), and
// extract.json gives the scale and the bounds in dataset units.
TEST(WriteExtraction, FilesAreInDatasetUnits) {
  auto model = SphereModel(3);
  model->set_scene_scale(0.25);
  model->frame(1, 1).root_init[kPoseT + 2] = 3.0;
  model->bones()[kBoneCenter] = 0.1;
  const std::string dir = TempDir("units");
  ExtractOptions options = Quick(16);
  WriteExtraction(*model, options, dir);
  const TriangleMesh canonical = ExtractCanonicalMesh(*model, options);
  EXPECT_EQ(ReadMesh(dir + "/canonical.ply").vertices, 0.25 * canonical.vertices);
  EXPECT_EQ(ReadMesh(dir + "/skinning.ply").vertices, 0.25 * canonical.vertices);
  EXPECT_EQ(ReadMesh(dir + "/bones.ply").vertices,
            0.25 * BoneEllipsoids(*model, options.bone_ellipsoid_sigmas,
                                  options.bone_ellipsoid_subdivisions)
                       .vertices);
  EXPECT_EQ(ReadMesh(dir + "/frames/video01_frame00001.ply").vertices,
            0.25 * ArticulateMesh(*model, canonical, 1, 1).vertices);
  EXPECT_EQ(MeshInDatasetUnits(*model, canonical).vertices, 0.25 * canonical.vertices);
  std::ifstream in(dir + "/extract.json");
  std::stringstream json;
  json << in.rdbuf();
  EXPECT_NE(json.str().find("\"scene_scale\": 0.25,"), std::string::npos) << json.str();
  EXPECT_NE(json.str().find("\"bounds_min\": [-0.25, -0.25, -0.25]"), std::string::npos)
      << json.str();
  fs::remove_all(dir);
}

// A model whose last frame's root pose is NaN: the error comes at that
// frame's mesh, after the canonical and earlier frame meshes were made;
// nothing of the run may be left in the folder (issue 66: 34 frame meshes
// and the canonical mesh were). A killed run's staging folder and
// temporary files are removed by the next run.
TEST(WriteExtraction, AFailingFrameLeavesNothingHalfWritten) {
  auto model = SphereModel(3);
  Pose& root = model->video(1).frames.back().root_delta;
  root.setConstant(std::nan(""));
  const std::string dir = TempDir("nan_frame");
  fs::create_directories(dir + "/.extract.staging-999999999/frames");
  std::ofstream(dir + "/.extract.staging-999999999/frames/old.ply") << "ply\n";
  std::ofstream(dir + "/canonical.ply.tmp.999999999.456") << "";
  std::ofstream(dir + "/keep.txt") << "not ours";
  std::ofstream(dir + "/notes.tmp.txt") << "not ours either";
  EXPECT_THROW(WriteExtraction(*model, Quick(24), dir), InputError);
  std::vector<std::string> left;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    left.push_back(fs::relative(e.path(), dir).string());
  }
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"keep.txt", "notes.tmp.txt"}));
  // The same folder with a good model: every file in place.
  root.setZero();
  root[0] = 1;  // identity quaternion [qw qx qy qz]
  WriteExtraction(*SphereModel(3), Quick(24), dir);
  EXPECT_TRUE(fs::exists(dir + "/canonical.ply"));
  EXPECT_TRUE(fs::exists(dir + "/frames"));
  for (const auto& e : fs::directory_iterator(dir)) {
    EXPECT_NE(e.path().filename().string().rfind(".extract.staging", 0), 0u) << e.path();
  }
  fs::remove_all(dir);
}

TEST(WriteExtraction, NoSurfaceIsAnErrorAndWritesNothing) {
  const auto model = SphereModel();
  const std::string dir = TempDir("empty");
  ExtractOptions options = Quick(8);
  options.grid.bounds_min.setConstant(0.8);
  options.grid.bounds_max.setConstant(1.0);
  EXPECT_THROW(WriteExtraction(*model, options, dir), InputError);
  EXPECT_FALSE(fs::exists(dir));
  options = Quick(8);
  options.bone_ellipsoid_sigmas = 0.0;
  EXPECT_THROW(WriteExtraction(*model, options, dir), InputError);
  options = Quick(8);
  options.min_component_fraction = 1.01;
  EXPECT_THROW(WriteExtraction(*model, options, dir), InputError);
  options.min_component_fraction = std::nan("");
  EXPECT_THROW(WriteExtraction(*model, options, dir), InputError);
  options = Quick(8);
  options.frames.all = false;
  options.frames.frames = {{0, 7}};
  EXPECT_THROW(WriteExtraction(*model, options, dir), InputError);
  EXPECT_FALSE(fs::exists(dir));
}

}  // namespace
}  // namespace banmo
