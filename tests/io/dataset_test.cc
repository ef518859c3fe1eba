#include "banmo/io/dataset.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "banmo/geometry/mesh_io.h"
#include "banmo/io/npy.h"
#include "banmo/util/error.h"
#include "test_dataset_util.h"

namespace banmo {
namespace {

namespace fs = std::filesystem;
using testing::LoadAll;
using testing::MakeGtMeshes;
using testing::MakeSmallDataset;
using testing::ReadText;
using testing::TempDir;
using testing::WriteText;
using testing::WriteValid;

cv::Mat ToFloat(const cv::Mat& m) {
  cv::Mat f;
  m.convertTo(f, CV_32F);
  return f;
}

double MaxAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(ToFloat(a), ToFloat(b), cv::NORM_INF);
}

// Writes a valid dataset with every kind of data into `dir`.
// Expects LoadDataset(dir) to throw an InputError whose message contains all
// the fragments (the file name, what was expected).
void ExpectLoadError(const std::string& dir, const std::vector<std::string>& fragments,
                     const LoadOptions& options = LoadAll()) {
  try {
    LoadDataset(dir, options);
    FAIL() << "LoadDataset accepted a bad dataset";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    for (const std::string& f : fragments) {
      EXPECT_NE(msg.find(f), std::string::npos) << "'" << f << "' not in: " << msg;
    }
  }
}

void ReplaceInFile(const std::string& path, const std::string& from, const std::string& to) {
  std::string text = ReadText(path);
  const std::size_t pos = text.find(from);
  ASSERT_NE(pos, std::string::npos) << from << " not in " << path << ":\n" << text;
  text.replace(pos, from.size(), to);
  WriteText(path, text);
}

TEST(Dataset, RoundTripKeepsEverything) {
  TempDir tmp;
  const Dataset d = MakeSmallDataset();
  const auto meshes = MakeGtMeshes(d);
  const std::string dir = tmp.path() + "/ds";
  WriteDataset(d, dir, &meshes);
  const Dataset l = LoadDataset(dir, LoadAll());
  ASSERT_EQ(l.videos.size(), d.videos.size());
  EXPECT_EQ(l.flow_gaps, d.flow_gaps);
  EXPECT_EQ(l.NumFrames(), d.NumFrames());
  EXPECT_EQ(l.NumSkippedFrames(), 0);
  for (std::size_t v = 0; v < d.videos.size(); ++v) {
    const Video& a = d.videos[v];
    const Video& b = l.videos[v];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.camera.width, b.camera.width);
    EXPECT_EQ(a.camera.height, b.camera.height);
    EXPECT_EQ(a.camera.intrinsics, b.camera.intrinsics);  // 17 significant digits: exact
    EXPECT_TRUE(b.present.flow && b.present.features && b.present.depth && b.present.gt_mesh &&
                b.present.root_poses_gt);
    ASSERT_EQ(a.frames.size(), b.frames.size());
    for (std::size_t t = 0; t < a.frames.size(); ++t) {
      const Frame& fa = a.frames[t];
      const Frame& fb = b.frames[t];
      EXPECT_EQ(fb.index, static_cast<int>(t));
      EXPECT_EQ(cv::norm(fa.rgb, fb.rgb, cv::NORM_INF), 0);
      EXPECT_EQ(cv::norm(fa.mask, fb.mask, cv::NORM_INF), 0);
      ASSERT_EQ(fb.features.type(), CV_16FC(kFeatureDim));
      EXPECT_EQ(0, std::memcmp(fa.features.data, fb.features.data,
                               fa.features.total() * fa.features.elemSize()));  // bit exact
      ASSERT_EQ(fa.flows.size(), fb.flows.size());
      for (const FlowField& ffa : fa.flows) {
        const FlowField* ffb = fb.FlowForGap(ffa.gap);
        ASSERT_NE(ffb, nullptr) << "gap " << ffa.gap;
        ASSERT_EQ(ffb->flow.type(), CV_16FC2);
        // KITTI quantisation: steps of 1/64 px, so at most 1/128 px error,
        // plus half-float rounding of the decoded value (|flow| < 8 px: step
        // 1/256, error <= 1/512 px).
        EXPECT_LE(MaxAbsDiff(ffa.flow, ffb->flow), 1.0 / 128 + 1.0 / 512);
        EXPECT_EQ(cv::norm(ffa.valid, ffb->valid, cv::NORM_INF), 0);
      }
      // 16-bit depth: max depth 4 -> unit 1e-4 (finest of {1,2,5}x10^k that
      // holds it), so the error is at most half a unit (+ float rounding).
      ASSERT_EQ(fb.depth.type(), CV_32FC1);
      EXPECT_LE(MaxAbsDiff(fa.depth, fb.depth), 0.5e-4 + 1e-6);
      EXPECT_EQ(fa.root_pose_init, fb.root_pose_init);
      ASSERT_TRUE(fb.root_pose_gt.has_value());
      EXPECT_LE((*fa.root_pose_gt - *fb.root_pose_gt).norm(), 1e-15);
      EXPECT_TRUE(fs::exists(fb.gt_mesh_path)) << fb.gt_mesh_path;
      const TriangleMesh m = ReadMesh(fb.gt_mesh_path);
      EXPECT_EQ(m.NumFaces(), 4);
      EXPECT_LE((m.vertices - meshes[v][t].vertices).cwiseAbs().maxCoeff(), 1e-6);
    }
  }
}

TEST(Dataset, RoundTripNpyFlowAndDepth) {
  TempDir tmp;
  WriteOptions o;
  o.flow_encoding = FlowEncoding::kNpy;
  o.depth_encoding = DepthEncoding::kNpy;
  const Dataset d = MakeSmallDataset();
  WriteDataset(d, tmp.path() + "/ds", o);
  const Dataset l = LoadDataset(tmp.path() + "/ds", LoadAll());
  for (std::size_t v = 0; v < d.videos.size(); ++v) {
    EXPECT_FALSE(l.videos[v].present.gt_mesh);
    for (std::size_t t = 0; t < d.videos[v].frames.size(); ++t) {
      const Frame& fa = d.videos[v].frames[t];
      const Frame& fb = l.videos[v].frames[t];
      EXPECT_EQ(MaxAbsDiff(fa.depth, fb.depth), 0);  // float32 stored: exact
      for (const FlowField& ffa : fa.flows) {
        EXPECT_EQ(MaxAbsDiff(ffa.flow, fb.FlowForGap(ffa.gap)->flow), 0);  // half stored: exact
        EXPECT_EQ(cv::norm(ffa.valid, fb.FlowForGap(ffa.gap)->valid, cv::NORM_INF), 0);
      }
    }
  }
}

TEST(Dataset, MinimalDatasetWithoutOptionalData) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  d.flow_gaps.clear();
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) {
      f.features.release();
      f.flows.clear();
      f.depth.release();
      f.root_pose_gt.reset();
    }
  }
  WriteDataset(d, tmp.path() + "/ds");
  const Dataset l = LoadDataset(tmp.path() + "/ds");
  EXPECT_FALSE(l.videos[0].present.flow || l.videos[0].present.features ||
               l.videos[0].present.depth || l.videos[0].present.root_poses_gt);
  EXPECT_TRUE(l.videos[0].frames[0].features.empty());
  EXPECT_EQ(std::set<std::string>({"rgb", "mask", "root_poses_init.txt"}), [&] {
    std::set<std::string> s;
    for (const auto& e : fs::directory_iterator(tmp.path() + "/ds/video0")) {
      s.insert(e.path().filename().string());
    }
    return s;
  }());
}

TEST(Dataset, GapLongerThanVideoGivesEmptyFlowFolders) {
  TempDir tmp;
  Dataset d = MakeSmallDataset(16, 12, 3);
  d.flow_gaps = {1, 4};  // 4 > 3 frames: no pairs
  for (Video& v : d.videos) {
    for (Frame& f : v.frames) {
      std::vector<FlowField> keep;
      for (const FlowField& ff : f.flows) {
        if (std::abs(ff.gap) == 1) keep.push_back(ff);
      }
      f.flows = keep;
    }
  }
  WriteDataset(d, tmp.path() + "/ds");
  const Dataset l = LoadDataset(tmp.path() + "/ds");
  EXPECT_EQ(l.flow_gaps, (std::vector<int>{1, 4}));
  EXPECT_EQ(l.videos[0].frames[1].flows.size(), 2u);
  EXPECT_TRUE(fs::is_empty(tmp.path() + "/ds/video0/flow/fw_4"));
}

TEST(Dataset, SkipFlagsOnlyAffectEmptyMasksAndLoadOptionsSkipData) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  d.videos[1].frames[2].mask.setTo(kMaskBackground);
  WriteDataset(d, tmp.path() + "/ds");
  LoadOptions o;
  o.load_features = false;
  o.load_flow = false;
  const Dataset l = LoadDataset(tmp.path() + "/ds", o);
  EXPECT_EQ(l.NumSkippedFrames(), 1);
  EXPECT_TRUE(l.videos[1].frames[2].skip);
  EXPECT_TRUE(l.videos[0].frames[0].features.empty());
  EXPECT_TRUE(l.videos[0].frames[0].flows.empty());
  EXPECT_TRUE(l.videos[0].frames[0].depth.empty());  // load_depth defaults to false
  EXPECT_TRUE(l.videos[0].present.features);
}

TEST(Dataset, WriteRefusesNonEmptyTargetUnlessOverwrite) {
  TempDir tmp;
  const Dataset d = MakeSmallDataset(16, 12, 3);
  const std::string dir = tmp.path() + "/ds";
  fs::create_directories(dir);  // empty folder: fine
  WriteDataset(d, dir);
  try {
    WriteDataset(d, dir);
    FAIL() << "overwrote a non-empty folder";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not empty"), std::string::npos) << e.what();
  }
  Dataset d2 = MakeSmallDataset(16, 12, 2);
  WriteDataset(d2, dir, nullptr, /*overwrite=*/true);
  EXPECT_EQ(LoadDataset(dir).NumFrames(), 4);
  // Nothing left beside the target (temporary or old folders).
  int entries = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) {
    (void)e;
    ++entries;
  }
  EXPECT_EQ(entries, 1);
}

TEST(Dataset, FailedWriteLeavesNothing) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  d.videos[1].frames[4].mask.at<unsigned char>(3, 3) = 17;  // invalid mask value, last frame
  const std::string dir = tmp.path() + "/ds";
  try {
    WriteDataset(d, dir);
    FAIL() << "wrote a bad mask";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mask value 17"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::is_empty(tmp.path()));
}

TEST(Dataset, WriteRejectsInconsistentMemory) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  d.videos[0].frames[2].flows.pop_back();
  EXPECT_THROW(WriteDataset(d, tmp.path() + "/a"), InputError);
  d = MakeSmallDataset();
  d.videos[0].frames[1].features.release();
  EXPECT_THROW(WriteDataset(d, tmp.path() + "/b"), InputError);
  d = MakeSmallDataset();
  d.videos[1].name = "bad/name";
  EXPECT_THROW(WriteDataset(d, tmp.path() + "/c"), InputError);
  d = MakeSmallDataset();
  d.videos[1].camera.intrinsics[0] = -3;
  EXPECT_THROW(WriteDataset(d, tmp.path() + "/d"), InputError);
  EXPECT_TRUE(fs::is_empty(tmp.path()));
}

TEST(Dataset, LoadedDatasetCanBeRewritten) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const Dataset l = LoadDataset(dir, LoadAll());
  WriteDataset(l, tmp.path() + "/copy");  // GT meshes copied from gt_mesh_path
  const Dataset c = LoadDataset(tmp.path() + "/copy", LoadAll());
  EXPECT_TRUE(c.videos[1].present.gt_mesh);
  EXPECT_EQ(testing::ReadText(c.videos[1].frames[4].gt_mesh_path),
            testing::ReadText(l.videos[1].frames[4].gt_mesh_path));
  EXPECT_EQ(MaxAbsDiff(c.videos[0].frames[2].flows[1].flow, l.videos[0].frames[2].flows[1].flow),
            0);  // already quantised: the second round trip is exact
  EXPECT_EQ(MaxAbsDiff(c.videos[0].frames[2].depth, l.videos[0].frames[2].depth), 0);
  // Loaded without features: re-writing would drop them, so it is refused.
  LoadOptions no_features;
  no_features.load_features = false;
  try {
    WriteDataset(LoadDataset(dir, no_features), tmp.path() + "/partial");
    FAIL() << "wrote a dataset whose features were not loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("features"), std::string::npos) << e.what();
  }
}

// ---- One test per bad input: write a valid dataset, break one thing. ----

TEST(DatasetBadInput, MissingFile) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  fs::remove(dir + "/video1/mask/00002.png");
  ExpectLoadError(dir, {"video1/mask/00002.png", "missing file"});
}

TEST(DatasetBadInput, MissingFlowFile) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  fs::remove(dir + "/video0/flow/bw_2/00004.png");
  ExpectLoadError(dir, {"flow/bw_2/00004.png", "missing file"});
}

TEST(DatasetBadInput, ExtraFile) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  fs::copy_file(dir + "/video0/rgb/00000.png", dir + "/video0/rgb/00005.png");
  ExpectLoadError(dir, {"video0/rgb/00005.png", "unexpected file"});
}

TEST(DatasetBadInput, ExtraFileInRootAndVideo) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  WriteText(dir + "/notes.txt", "hello");
  ExpectLoadError(dir, {"notes.txt", "unexpected file"});
  fs::remove(dir + "/notes.txt");
  fs::create_directories(dir + "/video1/extra");
  ExpectLoadError(dir, {"video1/extra", "unexpected folder"});
}

TEST(DatasetBadInput, ExtraFlowFileBeyondTheVideo) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  // fw_2 has frames 0..2 for 5 frames; frame 3 would point past the end.
  fs::copy_file(dir + "/video0/flow/fw_2/00000.png", dir + "/video0/flow/fw_2/00003.png");
  ExpectLoadError(dir, {"fw_2/00003.png", "unexpected file"});
}

TEST(DatasetBadInput, TruncatedImage) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video1/rgb/00003.png";
  const std::string bytes = ReadText(path);
  WriteText(path, bytes.substr(0, bytes.size() / 2));
  ExpectLoadError(dir, {"video1/rgb/00003.png", "truncated"});
}

TEST(DatasetBadInput, TruncatedFlowWithoutLoadingFlow) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video1/flow/fw_1/00003.png";
  const std::string bytes = ReadText(path);
  WriteText(path, bytes.substr(0, bytes.size() - 5));
  LoadOptions o;
  o.load_flow = false;  // header + tail checks still catch it
  ExpectLoadError(dir, {"fw_1/00003.png", "truncated"}, o);
}

TEST(DatasetBadInput, UnreadableImage) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  WriteText(dir + "/video0/mask/00001.png", "this is not a PNG file, but long enough to look");
  ExpectLoadError(dir, {"video0/mask/00001.png", "not a PNG"});
}

TEST(DatasetBadInput, CorruptImageData) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video0/rgb/00001.png";
  std::string bytes = ReadText(path);
  // Overwrite the middle of the compressed data, keep signature, IHDR, IEND.
  for (std::size_t i = 60; i < bytes.size() - 20; ++i) bytes[i] = static_cast<char>(i * 37);
  WriteText(path, bytes);
  ExpectLoadError(dir, {"video0/rgb/00001.png", "unreadable PNG"});
}

TEST(DatasetBadInput, WrongImageType) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::imwrite(dir + "/video0/rgb/00002.png", cv::Mat(20, 24, CV_8UC1, cv::Scalar(3)));
  ExpectLoadError(dir, {"video0/rgb/00002.png", "expected a 8-bit PNG with 3 channel(s)"});
}

TEST(DatasetBadInput, MaskSizeMismatch) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::imwrite(dir + "/video1/mask/00000.png", cv::Mat(20, 23, CV_8UC1, cv::Scalar(255)));
  ExpectLoadError(dir, {"video1/mask/00000.png", "23x20", "24x20"});
}

TEST(DatasetBadInput, FlowSizeMismatch) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::imwrite(dir + "/video0/flow/fw_1/00001.png",
              cv::Mat(21, 24, CV_16UC3, cv::Scalar(1, 32768, 32768)));
  ExpectLoadError(dir, {"flow/fw_1/00001.png", "24x21", "24x20"});
}

TEST(DatasetBadInput, FeatureSizeMismatch) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  WriteNpy(dir + "/video0/features/00003.npy", cv::Mat::zeros(20, 25, CV_16FC(kFeatureDim)));
  ExpectLoadError(dir, {"video0/features/00003.npy", "25x20", "24x20"});
}

TEST(DatasetBadInput, FeatureWrongChannelsOrDtype) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  WriteNpy(dir + "/video0/features/00003.npy", cv::Mat::zeros(20, 24, CV_16FC(8)));
  ExpectLoadError(dir, {"features/00003.npy", "(height, width, 16)"});
  WriteNpy(dir + "/video0/features/00003.npy", cv::Mat::zeros(20, 24, CV_32FC(kFeatureDim)));
  ExpectLoadError(dir, {"features/00003.npy", "float16"});
}

TEST(DatasetBadInput, NaNFeatures) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video1/features/00004.npy";
  cv::Mat f = ReadNpy(path);
  cv::Mat f32;
  f.convertTo(f32, CV_32F);
  f32.ptr<float>(5)[7 * kFeatureDim + 3] = std::numeric_limits<float>::quiet_NaN();
  f32.convertTo(f, CV_16F);
  WriteNpy(path, f);
  ExpectLoadError(dir, {"video1/features/00004.npy", "NaN or Inf", "x=7, y=5, channel 3"});
}

TEST(DatasetBadInput, InfFlow) {
  TempDir tmp;
  WriteOptions o;
  o.flow_encoding = FlowEncoding::kNpy;  // the PNG encoding cannot hold NaN/Inf
  const std::string dir = WriteValid(tmp, o);
  const std::string path = dir + "/video0/flow/bw_1/00002.npy";
  cv::Mat f = ReadNpy(path);
  cv::Mat f32;
  f.convertTo(f32, CV_32F);
  f32.at<cv::Vec3f>(2, 9)[1] = std::numeric_limits<float>::infinity();
  f32.convertTo(f, CV_16F);
  WriteNpy(path, f);
  ExpectLoadError(dir, {"flow/bw_1/00002.npy", "NaN or Inf", "x=9, y=2"});
}

TEST(DatasetBadInput, FlowValidChannel) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::imwrite(dir + "/video0/flow/fw_1/00001.png",
              cv::Mat(20, 24, CV_16UC3, cv::Scalar(2, 32768, 32768)));
  ExpectLoadError(dir, {"flow/fw_1/00001.png", "valid channel", "0 or 1"});
}

TEST(DatasetBadInput, BadIntrinsics) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  ReplaceInFile(dir + "/manifest.yaml", "[31.5, 31.25", "[-31.5, 31.25");
  ExpectLoadError(dir, {"manifest.yaml", "bad intrinsics", "fx, fy > 0"});
}

TEST(DatasetBadInput, PrincipalPointOutsideImage) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  ReplaceInFile(dir + "/manifest.yaml", "31.25, 12, 10.5]", "31.25, 12, 99]");
  ExpectLoadError(dir, {"manifest.yaml", "bad intrinsics", "principal point"});
}

TEST(DatasetBadInput, FrameCountMismatch) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  ReplaceInFile(dir + "/manifest.yaml", "frames: 5", "frames: 6");
  ExpectLoadError(dir, {"video0/rgb/00005.png", "frame-count mismatch", "6 frames"});
}

TEST(DatasetBadInput, UnknownManifestKeys) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string manifest = ReadText(dir + "/manifest.yaml");
  WriteText(dir + "/manifest.yaml", manifest + "colour: red\n");
  ExpectLoadError(dir, {"manifest.yaml", "unknown key 'colour'"});
  WriteText(dir + "/manifest.yaml", manifest);
  ReplaceInFile(dir + "/manifest.yaml", "frames: 5", "frames: 5\n    fps: 30");
  ExpectLoadError(dir, {"manifest.yaml", "unknown key 'videos[0].fps'", "expected one of"});
  WriteText(dir + "/manifest.yaml", manifest);
  ReplaceInFile(dir + "/manifest.yaml", "root_poses_gt]", "root_poses_gt, normals]");
  ExpectLoadError(dir, {"manifest.yaml", "unknown entry 'normals'"});
}

TEST(DatasetBadInput, BadManifestValues) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string manifest = ReadText(dir + "/manifest.yaml");
  ReplaceInFile(dir + "/manifest.yaml", "feature_dim: 16", "feature_dim: 8");
  ExpectLoadError(dir, {"manifest.yaml", "feature_dim", "expected 16"});
  WriteText(dir + "/manifest.yaml", manifest);
  ReplaceInFile(dir + "/manifest.yaml", "frames: 5", "frames: five");
  ExpectLoadError(dir, {"manifest.yaml", "frames", "positive integer"});
  WriteText(dir + "/manifest.yaml", manifest);
  ReplaceInFile(dir + "/manifest.yaml", "version: 1", "version: 7");
  ExpectLoadError(dir, {"manifest.yaml", "version 7"});
  WriteText(dir + "/manifest.yaml", "videos: [\n");
  ExpectLoadError(dir, {"manifest.yaml", "invalid YAML"});
  fs::remove(dir + "/manifest.yaml");
  ExpectLoadError(dir, {"manifest.yaml", "cannot open"});
}

TEST(DatasetBadInput, BadPoseLines) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  const std::string path = dir + "/video1/root_poses_init.txt";
  const std::string good = ReadText(path);
  // Line 1 is the comment header; line 3 is frame 1.
  std::vector<std::string> lines;
  std::stringstream ss(good);
  for (std::string l; std::getline(ss, l);) lines.push_back(l);
  const auto write_with_line3 = [&](const std::string& l3) {
    std::string text;
    for (std::size_t i = 0; i < lines.size(); ++i) text += (i == 2 ? l3 : lines[i]) + "\n";
    WriteText(path, text);
  };
  write_with_line3("1 0 0 0 0 0");
  ExpectLoadError(dir, {"video1/root_poses_init.txt:3", "expected 7 numbers", "found 6"});
  write_with_line3("1 0 0 0 0 0 abc");
  ExpectLoadError(dir, {"root_poses_init.txt:3", "'abc' is not a number"});
  write_with_line3("2 0 0 0 0 0 3");
  ExpectLoadError(dir, {"root_poses_init.txt:3", "norm 2"});
  write_with_line3("1 0 0 0 0 0 nan");
  ExpectLoadError(dir, {"root_poses_init.txt:3", "non-finite"});
  WriteText(path, good + "1 0 0 0 0 0 3\n");
  ExpectLoadError(dir, {"root_poses_init.txt", "expected 5 pose lines", "found 6"});
}

TEST(DatasetBadInput, BadMaskValue) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::Mat m(20, 24, CV_8UC1, cv::Scalar(0));
  m.at<unsigned char>(4, 6) = 200;
  cv::imwrite(dir + "/video0/mask/00001.png", m);
  ExpectLoadError(dir, {"video0/mask/00001.png", "mask value 200", "x=6, y=4"});
}

// Ground truth beside degraded data (banmo synth --realism casual): exact
// masks in mask_gt/ and the true intrinsics as intrinsics_gt round-trip, are
// loaded only when asked, and bad ones are errors naming the file and key.
TEST(Dataset, MaskGtAndIntrinsicsGtRoundTrip) {
  TempDir tmp;
  Dataset d = MakeSmallDataset();
  for (Video& v : d.videos) {
    v.intrinsics_gt = Eigen::Vector4d(40, 40, 12, 10);
    for (Frame& f : v.frames) {
      f.mask_gt = f.mask.clone();
      f.mask_gt.at<unsigned char>(3, 4) = kMaskObject;
    }
  }
  const auto meshes = MakeGtMeshes(d);
  const std::string dir = tmp.path() + "/ds";
  WriteDataset(d, dir, &meshes);
  EXPECT_NE(ReadText(dir + "/manifest.yaml").find("intrinsics_gt: [40, 40, 12, 10]"),
            std::string::npos);
  LoadOptions options = LoadAll();
  options.load_mask_gt = true;
  const Dataset loaded = LoadDataset(dir, options);
  for (std::size_t v = 0; v < d.videos.size(); ++v) {
    EXPECT_TRUE(loaded.videos[v].present.mask_gt);
    ASSERT_TRUE(loaded.videos[v].intrinsics_gt.has_value());
    EXPECT_EQ(*loaded.videos[v].intrinsics_gt, Eigen::Vector4d(40, 40, 12, 10));
    for (std::size_t t = 0; t < d.videos[v].frames.size(); ++t) {
      EXPECT_EQ(MaxAbsDiff(loaded.videos[v].frames[t].mask_gt, d.videos[v].frames[t].mask_gt), 0);
    }
  }
  EXPECT_TRUE(LoadDataset(dir).videos[0].frames[0].mask_gt.empty());
  // Rewriting a dataset loaded without its ground-truth masks would drop them.
  try {
    WriteDataset(LoadDataset(dir, LoadAll()), tmp.path() + "/copy", &meshes);
    FAIL() << "mask_gt dropped silently";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("lists mask_gt"), std::string::npos) << e.what();
  }

  cv::Mat bad(20, 24, CV_8UC1, cv::Scalar(0));
  bad.at<unsigned char>(2, 3) = 7;
  cv::imwrite(dir + "/video0/mask_gt/00001.png", bad);
  ExpectLoadError(dir, {"video0/mask_gt/00001.png", "mask value 7", "x=3, y=2"}, options);
  fs::remove(dir + "/video0/mask_gt/00001.png");
  ExpectLoadError(dir, {"video0/mask_gt/00001.png", "missing file"}, options);
  ReplaceInFile(dir + "/manifest.yaml", "intrinsics_gt: [40, 40, 12, 10]",
                "intrinsics_gt: [40, 40, 12]");
  ExpectLoadError(dir, {"manifest.yaml", "intrinsics_gt", "[fx, fy, cx, cy]"}, options);
}

TEST(DatasetBadInput, NotAPlyMesh) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  WriteText(dir + "/video0/gt_mesh/00001.ply", "solid stl\n");
  ExpectLoadError(dir, {"video0/gt_mesh/00001.ply", "not a PLY"});
}

TEST(DatasetBadInput, NotADatasetFolder) {
  TempDir tmp;
  ExpectLoadError(tmp.path() + "/nope", {"nope", "not a folder"});
}

TEST(DatasetBadInput, EmptyMaskWarnsAndSkips) {
  TempDir tmp;
  const std::string dir = WriteValid(tmp);
  cv::imwrite(dir + "/video1/mask/00003.png", cv::Mat(20, 24, CV_8UC1, cv::Scalar(kMaskIgnore)));
  const Dataset d = LoadDataset(dir);
  EXPECT_TRUE(d.videos[1].frames[3].skip);
  EXPECT_EQ(d.NumSkippedFrames(), 1);
}

TEST(Dataset, HasPixelFeaturesCountsOnlyFramesNotSkipped) {
  Dataset d;
  d.videos.resize(2);
  d.videos[0].frames.resize(2);
  d.videos[1].frames.resize(1);
  EXPECT_FALSE(d.HasPixelFeatures());
  Frame& f = d.videos[1].frames[0];
  f.features = cv::Mat(4, 4, CV_16FC(kFeatureDim), cv::Scalar::all(0));
  EXPECT_TRUE(d.HasPixelFeatures());
  f.skip = true;  // an empty or held-out frame's features are never read
  EXPECT_FALSE(d.HasPixelFeatures());
}

TEST(Dataset, IsPixelFeatureIsAnyNonzeroChannel) {
  std::vector<cv::float16_t> f(kFeatureDim, cv::float16_t(0.0f));
  EXPECT_FALSE(IsPixelFeature(f.data()));
  f[7] = cv::float16_t(-0.0f);  // negative zero is zero
  EXPECT_FALSE(IsPixelFeature(f.data()));
  // The smallest positive half (2^-24, subnormal) in the last channel counts:
  // the rule is exact, with no threshold.
  f[kFeatureDim - 1] = cv::float16_t::fromBits(1);
  ASSERT_GT(static_cast<float>(f[kFeatureDim - 1]), 0.0f);
  EXPECT_TRUE(IsPixelFeature(f.data()));
  f[kFeatureDim - 1] = cv::float16_t(0.0f);
  f[0] = cv::float16_t(-0.25f);
  EXPECT_TRUE(IsPixelFeature(f.data()));
}

TEST(PoseFile, RoundTripAndComments) {
  TempDir tmp;
  std::vector<Pose> poses = {PoseIdentity(), PoseFromAngleAxis(Eigen::Vector3d(0.1, -0.2, 0.3),
                                                               Eigen::Vector3d(1e-9, 2.5, -3))};
  WritePoseFile(tmp.path() + "/p.txt", poses);
  const std::vector<Pose> back = ReadPoseFile(tmp.path() + "/p.txt", 2);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_LE((back[1] - poses[1]).norm(), 1e-15);
  EXPECT_EQ(back[0], poses[0]);
  // A comment (e.g. banmo synth's pose-noise record) becomes "# " lines after
  // the header; the poses read back unchanged.
  WritePoseFile(tmp.path() + "/c.txt", poses, "noise: gaussian\nmean 50 deg");
  std::ifstream in(tmp.path() + "/c.txt");
  std::string header, line1, line2;
  std::getline(in, header);
  std::getline(in, line1);
  std::getline(in, line2);
  EXPECT_EQ(header, "# qw qx qy qz tx ty tz (camera_from_root), one line per frame");
  EXPECT_EQ(line1, "# noise: gaussian");
  EXPECT_EQ(line2, "# mean 50 deg");
  EXPECT_EQ(ReadPoseFile(tmp.path() + "/c.txt", 2), back);
}

}  // namespace
}  // namespace banmo
