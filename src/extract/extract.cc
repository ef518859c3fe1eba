#include "banmo/extract/extract.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include "banmo/deform/bones.h"
#include "banmo/geometry/box.h"
#include "banmo/geometry/mesh_io.h"
#include "banmo/geometry/se3.h"
#include "banmo/io/npy.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"
#include "banmo/util/timer.h"

namespace banmo {
namespace {

// Points per colour-MLP call (bounds the cache memory, as the SDF batches).
constexpr int kColorBatch = 16384;

int Digits(int n) {
  int d = 1;
  while (n >= 10) {
    n /= 10;
    ++d;
  }
  return d;
}

// Parses a non-negative decimal integer; false on anything else.
bool ParseIndex(const std::string& s, int* out) {
  if (s.empty() || s.size() > 9) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  *out = std::stoi(s);
  return true;
}

// Unit icosphere, counter-clockwise seen from outside.
TriangleMesh Icosphere(int subdivisions) {
  const double p = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::Vector3d> v = {{-1, p, 0}, {1, p, 0}, {-1, -p, 0}, {1, -p, 0},
                                    {0, -1, p}, {0, 1, p}, {0, -1, -p}, {0, 1, -p},
                                    {p, 0, -1}, {p, 0, 1}, {-p, 0, -1}, {-p, 0, 1}};
  for (auto& x : v) x.normalize();
  std::vector<Eigen::Vector3i> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                    {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                    {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                    {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      v.push_back((v[a] + v[b]).normalized());
      const int id = static_cast<int>(v.size()) - 1;
      midpoint.emplace(key, id);
      return id;
    };
    std::vector<Eigen::Vector3i> g;
    for (const auto& t : f) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      g.push_back({t[0], ab, ca});
      g.push_back({t[1], bc, ab});
      g.push_back({t[2], ca, bc});
      g.push_back({ab, bc, ca});
    }
    f.swap(g);
  }
  TriangleMesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) mesh.vertices.col(i) = v[i];
  mesh.faces.resize(3, static_cast<Eigen::Index>(f.size()));
  for (size_t i = 0; i < f.size(); ++i) {
    Eigen::Vector3i t = f[i];
    const Eigen::Vector3d n = (v[t[1]] - v[t[0]]).cross(v[t[2]] - v[t[0]]);
    if (n.dot(v[t[0]] + v[t[1]] + v[t[2]]) < 0) std::swap(t[1], t[2]);
    mesh.faces.col(i) = t;
  }
  return mesh;
}

void CheckFrame(const Model& model, int video, int frame, const char* what) {
  if (video < 0 || video >= model.num_videos()) {
    ThrowInputError(what, ": video ", video, " out of range (the model has ", model.num_videos(),
                    " videos)");
  }
  const int n = static_cast<int>(model.video(video).frames.size());
  if (frame < 0 || frame >= n) {
    ThrowInputError(what, ": frame ", frame, " of video ", video, " out of range (", n, " frames)");
  }
}

}  // namespace

void ExtractOptions::Check() const {
  grid.Check("extract.grid");
  if (color_video < -1) ThrowInputError("extract.color_video: expected >= -1, got ", color_video);
  if (!(bone_ellipsoid_sigmas > 0) || !std::isfinite(bone_ellipsoid_sigmas)) {
    ThrowInputError("extract.bone_ellipsoid_sigmas: expected a finite value > 0");
  }
  if (!(min_component_fraction >= 0.0 && min_component_fraction <= 1.0)) {
    ThrowInputError("extract.min_component_fraction: expected a number in [0, 1], got ",
                    min_component_fraction);
  }
  if (bone_ellipsoid_subdivisions < 0 || bone_ellipsoid_subdivisions > 4) {
    ThrowInputError("extract.bone_ellipsoid_subdivisions: expected 0..4, got ",
                    bone_ellipsoid_subdivisions);
  }
}

FrameSelection ParseFrameSelection(const std::string& text, const Model& model,
                                   const std::string& flag) {
  FrameSelection sel;
  if (text == "all") return sel;
  sel.all = false;
  if (text == "none") return sel;
  // Items separated by commas; empty items (",,", a trailing comma) are errors.
  std::vector<std::string> items(1);
  for (char c : text) {
    if (c == ',') {
      items.emplace_back();
    } else {
      items.back().push_back(c);
    }
  }
  std::string item;
  auto bad = [&](const std::string& why) {
    ThrowInputError(flag, " '", text, "': item '", item, "' ", why,
                    " (expected all, none, or a comma-separated list of V:T, V:T0-T1, V:*)");
  };
  for (const std::string& it : items) {
    item = it;
    if (item.empty()) bad("is empty");
    const size_t colon = item.find(':');
    if (colon == std::string::npos) bad("has no ':'");
    int v = 0;
    if (!ParseIndex(item.substr(0, colon), &v)) bad("has no valid video index");
    if (v >= model.num_videos()) {
      bad("names video " + std::to_string(v) + " but the model has " +
          std::to_string(model.num_videos()) + " videos");
    }
    const int n = static_cast<int>(model.video(v).frames.size());
    const std::string rest = item.substr(colon + 1);
    int t0 = 0, t1 = 0;
    if (rest == "*") {
      t0 = 0;
      t1 = n - 1;
    } else if (const size_t dash = rest.find('-'); dash != std::string::npos) {
      if (!ParseIndex(rest.substr(0, dash), &t0) || !ParseIndex(rest.substr(dash + 1), &t1) ||
          t1 < t0) {
        bad("has no valid frame range");
      }
    } else {
      if (!ParseIndex(rest, &t0)) bad("has no valid frame index");
      t1 = t0;
    }
    if (t1 >= n) {
      bad("names frame " + std::to_string(t1) + " but video " + std::to_string(v) + " has " +
          std::to_string(n) + " frames");
    }
    for (int t = t0; t <= t1; ++t) sel.frames.emplace_back(v, t);
  }
  if (sel.frames.empty()) bad("selects no frame");
  return sel;
}

FieldBatchFunction ModelSdfFunction(const Model& model) {
  auto batch = std::make_shared<FieldBatch>();
  return [&model, batch](const Eigen::Matrix3Xd& points, Eigen::VectorXd* values) {
    batch->x = points;
    model.field().ForwardSdfBatch(model.sdf(), batch.get(), /*sdf_gradient=*/false);
    *values = batch->sdf;
  };
}

Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> CanonicalColors(const Model& model,
                                                               const Eigen::Matrix3Xd& points,
                                                               int video) {
  const CanonicalField& field = model.field();
  const int n = static_cast<int>(points.cols());
  const int A = field.AppearanceCodeDim();
  Eigen::VectorXd code = Eigen::VectorXd::Zero(A);
  if (video >= 0 && video < model.num_videos() && A > 0) {
    code = Eigen::Map<const Eigen::VectorXd>(model.video(video).appearance.data(), A);
  }
  Eigen::Matrix<std::uint8_t, 3, Eigen::Dynamic> colors(3, n);
  FieldBatch batch;
  for (int begin = 0; begin < n; begin += kColorBatch) {
    const int m = std::min(kColorBatch, n - begin);
    batch.x = points.middleCols(begin, m);
    if (field.options().use_view_direction) {
      batch.view_dir = Eigen::Vector3d::UnitZ().replicate(1, m);
    }
    if (A > 0) batch.appearance = code.replicate(1, m);
    field.ForwardBatch(model.sdf(), model.color(), &batch, /*input_jacobians=*/false);
    for (int j = 0; j < m; ++j) {
      for (int c = 0; c < 3; ++c) {
        const double value = std::clamp(batch.rgb(c, j), 0.0, 1.0);
        colors(c, begin + j) = static_cast<std::uint8_t>(std::lround(255.0 * value));
      }
    }
  }
  return colors;
}

namespace {

// color_video must name one of the model's videos (or -1).
void CheckColorVideo(const Model& model, const ExtractOptions& options) {
  if (options.color_video >= model.num_videos()) {
    ThrowInputError("extract.color_video (--color-video): video ", options.color_video,
                    " does not exist: the model has ", model.num_videos(),
                    " video(s) (expected -1 for no appearance code, or 0..", model.num_videos() - 1,
                    ")");
  }
}

}  // namespace

TriangleMesh ExtractCanonicalMesh(const Model& model, const ExtractOptions& options,
                                  MarchingCubesStats* stats) {
  options.Check();
  CheckColorVideo(model, options);
  TriangleMesh mesh = MarchingCubes(ModelSdfFunction(model), options.grid, stats);
  mesh = KeepLargeComponents(mesh, options.min_component_fraction);
  if (mesh.NumVertices() > 0)
    mesh.colors = CanonicalColors(model, mesh.vertices, options.color_video);
  return mesh;
}

Eigen::MatrixXd ForwardDeltaLogits(const Model& model, const Eigen::Matrix3Xd& points) {
  if (!model.DeltaSkinningIsNonZero()) return Eigen::MatrixXd(0, points.cols());
  const DeltaSkinning& delta = *model.delta_skinning();
  const int n = static_cast<int>(points.cols());
  Eigen::MatrixXd logits(model.num_bones(), n);
  const Eigen::Map<const Eigen::VectorXd> code(model.rest_pose_code(), delta.CodeDim());
  constexpr int kChunk = 16384;  // bounds the MLP cache's memory
  for (int start = 0; start < n; start += kChunk) {
    const int count = std::min(kChunk, n - start);
    DeltaSkinningBatch batch;
    batch.x = points.middleCols(start, count);
    batch.codes = code.replicate(1, count);
    delta.ForwardBatch(model.delta_skinning_params(), &batch, false);
    logits.middleCols(start, count) = batch.logits;
  }
  return logits;
}

TriangleMesh ArticulateMesh(const Model& model, const TriangleMesh& canonical, int video,
                            int frame) {
  CheckFrame(model, video, frame, "ArticulateMesh");
  const FrameParameters& f = model.frame(video, frame);
  const Pose camera_from_root = model.RootPose(video, frame);
  const int B = model.num_bones();
  CHECK_EQ(static_cast<int>(f.bones_t.size()), kPoseSize * B);
  TriangleMesh posed = canonical;
  const Eigen::MatrixXd delta = ForwardDeltaLogits(model, canonical.vertices);
  ParallelFor(canonical.NumVertices(), [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const double* x_canonical = canonical.vertices.col(i).data();
      double x_in_root[3];
      ForwardWarp(B, model.bones(), f.bones_t.data(), x_canonical, x_in_root,
                  delta.rows() > 0 ? delta.col(i).data() : nullptr);
      PoseTransformPoint(camera_from_root.data(), x_in_root, posed.vertices.col(i).data());
    }
  });
  return posed;
}

Eigen::MatrixXd SkinningWeightsAt(const Model& model, const Eigen::Matrix3Xd& points) {
  const int B = model.num_bones();
  const int n = static_cast<int>(points.cols());
  Eigen::MatrixXd weights(B, n);
  if (B == 0) return weights;
  const Eigen::MatrixXd delta = ForwardDeltaLogits(model, points);
  ParallelFor(n, [&](int begin, int end) {
    std::vector<double> logits(B);
    for (int i = begin; i < end; ++i) {
      for (int b = 0; b < B; ++b) {
        logits[b] = BoneLogit(model.bones() + kBoneSize * b, points.col(i).data());
        if (delta.rows() > 0) logits[b] += delta(b, i);
      }
      SkinningWeights(B, logits.data(), weights.col(i).data());
    }
  });
  return weights;
}

Eigen::MatrixXd EmbeddingAt(const Model& model, const Eigen::Matrix3Xd& points) {
  const CanonicalField& field = model.field();
  const int n = static_cast<int>(points.cols());
  Eigen::MatrixXd psi(CanonicalField::EmbeddingDim(), n);
  ParallelFor(n, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      field.EvaluateEmbedding(model.embedding(), points.col(i).data(), psi.col(i).data());
    }
  });
  return psi;
}

TriangleMesh MeshInDatasetUnits(const Model& model, TriangleMesh mesh) {
  mesh.vertices *= model.scene_scale();
  return mesh;
}

Eigen::Matrix<std::uint8_t, 3, 1> BonePaletteColor(int bone) {
  // Twelve well-separated colours, then golden-ratio hues.
  static const std::uint8_t kPalette[12][3] = {{230, 25, 75},  {60, 180, 75},  {0, 130, 200},
                                               {245, 130, 48}, {145, 30, 180}, {70, 240, 240},
                                               {240, 50, 230}, {210, 245, 60}, {250, 190, 212},
                                               {0, 128, 128},  {170, 110, 40}, {128, 0, 0}};
  Eigen::Matrix<std::uint8_t, 3, 1> out;
  if (bone >= 0 && bone < 12) {
    out << kPalette[bone][0], kPalette[bone][1], kPalette[bone][2];
    return out;
  }
  const double hue = std::fmod(0.61803398875 * bone, 1.0) * 6.0;
  const int sector = static_cast<int>(hue) % 6;
  const double frac = hue - std::floor(hue);
  const double s = 0.75, v = 0.9;
  const double p = v * (1 - s), q = v * (1 - s * frac), t = v * (1 - s * (1 - frac));
  const double rgb[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
  for (int c = 0; c < 3; ++c) out[c] = static_cast<std::uint8_t>(std::lround(255 * rgb[sector][c]));
  return out;
}

TriangleMesh ColorByDominantBone(const TriangleMesh& canonical, const Eigen::MatrixXd& weights) {
  CHECK_EQ(weights.cols(), canonical.NumVertices());
  TriangleMesh out = canonical;
  out.colors.resize(3, canonical.NumVertices());
  for (int i = 0; i < canonical.NumVertices(); ++i) {
    Eigen::Index b = 0;
    if (weights.rows() > 0) weights.col(i).maxCoeff(&b);
    out.colors.col(i) = BonePaletteColor(static_cast<int>(b));
  }
  return out;
}

TriangleMesh BoneEllipsoids(const Model& model, double sigmas, int subdivisions) {
  const int B = model.num_bones();
  TriangleMesh out;
  if (B == 0) return out;
  const TriangleMesh sphere = Icosphere(subdivisions);
  const int nv = sphere.NumVertices(), nf = sphere.NumFaces();
  out.vertices.resize(3, nv * B);
  out.faces.resize(3, nf * B);
  out.colors.resize(3, nv * B);
  for (int b = 0; b < B; ++b) {
    const double* bone = model.bones() + kBoneSize * b;
    for (int i = 0; i < nv; ++i) {
      double local[3];
      for (int k = 0; k < 3; ++k) {
        local[k] = sigmas * std::exp(bone[kBoneLogScale + k]) * sphere.vertices(k, i);
      }
      double rotated[3];
      ceres::QuaternionRotatePoint(bone + kBoneQw, local, rotated);
      for (int k = 0; k < 3; ++k) out.vertices(k, b * nv + i) = bone[kBoneCenter + k] + rotated[k];
      out.colors.col(b * nv + i) = BonePaletteColor(b);
    }
    // Positive scales and a rotation keep the orientation of the faces.
    out.faces.middleCols(b * nf, nf) = sphere.faces.array() + b * nv;
  }
  return out;
}

ExtractionSummary WriteExtraction(const Model& model, const ExtractOptions& options,
                                  const std::string& out_dir,
                                  const std::function<void(int done, int total)>& progress) {
  options.Check();
  CheckColorVideo(model, options);
  std::vector<std::pair<int, int>> frames;
  if (options.frames.all) {
    for (int v = 0; v < model.num_videos(); ++v) {
      for (int t = 0; t < static_cast<int>(model.video(v).frames.size()); ++t) {
        frames.emplace_back(v, t);
      }
    }
  } else {
    frames = options.frames.frames;
    for (const auto& [v, t] : frames) CheckFrame(model, v, t, "extract.frames");
  }

  ExtractionSummary summary;
  Timer timer;
  const TriangleMesh canonical = ExtractCanonicalMesh(model, options);
  summary.canonical_seconds = timer.Seconds();
  if (canonical.NumFaces() == 0) {
    const GridOptions& g = options.grid;
    ThrowInputError("extract: the SDF has no zero crossing inside the bounds [",
                    g.bounds_min.transpose(), "] - [", g.bounds_max.transpose(),
                    "] (model units) at resolution ", g.resolution, "; nothing written to ",
                    out_dir);
  }
  summary.canonical_vertices = canonical.NumVertices();
  summary.canonical_faces = canonical.NumFaces();

  namespace fs = std::filesystem;
  // Everything is written to a staging folder first and moved into out_dir
  // only once all of it is written: a failure (a non-finite mesh, a full
  // disk) or a kill leaves no partial set of meshes.
  StagedOutput staged(out_dir, "extract");
  const fs::path out(staged.path());
  WritePly((out / "canonical.ply").string(), MeshInDatasetUnits(model, canonical));

  const int B = model.num_bones();
  if (B > 0) {
    const Eigen::MatrixXd weights = SkinningWeightsAt(model, canonical.vertices);
    WritePly((out / "skinning.ply").string(),
             MeshInDatasetUnits(model, ColorByDominantBone(canonical, weights)));
    WritePly((out / "bones.ply").string(),
             MeshInDatasetUnits(model, BoneEllipsoids(model, options.bone_ellipsoid_sigmas,
                                                      options.bone_ellipsoid_subdivisions)));
    // (vertices, B) float32, row-major.
    cv::Mat data(canonical.NumVertices(), B, CV_32F);
    for (int i = 0; i < canonical.NumVertices(); ++i) {
      for (int b = 0; b < B; ++b) data.at<float>(i, b) = static_cast<float>(weights(b, i));
    }
    WriteNpy((out / "skinning_weights.npy").string(), data, /*channel_axis=*/false);
  }

  {
    // (vertices, 16) float32, row-major.
    const Eigen::MatrixXd psi = EmbeddingAt(model, canonical.vertices);
    cv::Mat data(canonical.NumVertices(), static_cast<int>(psi.rows()), CV_32F);
    for (int i = 0; i < canonical.NumVertices(); ++i) {
      for (int c = 0; c < psi.rows(); ++c) data.at<float>(i, c) = static_cast<float>(psi(c, i));
    }
    WriteNpy((out / "embedding.npy").string(), data, /*channel_axis=*/false);
  }

  const int num_frames = static_cast<int>(frames.size());
  if (progress) progress(0, num_frames);
  timer.Reset();
  if (!frames.empty()) {
    const fs::path frame_dir = out / "frames";
    MakeDirectories(frame_dir.string());
    int max_frames = 1;
    for (int v = 0; v < model.num_videos(); ++v) {
      max_frames = std::max(max_frames, static_cast<int>(model.video(v).frames.size()));
    }
    const int vw = std::max(2, Digits(std::max(0, model.num_videos() - 1)));
    const int tw = std::max(5, Digits(max_frames - 1));
    std::set<std::string> written;
    for (const auto& [v, t] : frames) {
      char name[64];
      std::snprintf(name, sizeof(name), "video%0*d_frame%0*d.ply", vw, v, tw, t);
      WritePly((frame_dir / name).string(),
               MeshInDatasetUnits(model, ArticulateMesh(model, canonical, v, t)));
      written.insert(name);
      ++summary.frames_written;
      if (progress) progress(summary.frames_written, num_frames);
    }
    // Meshes of an earlier run left in frames/ would be picked up by
    // `banmo eval --pred OUT/frames`: say so (they are not deleted).
    int stale = 0;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(fs::path(out_dir) / "frames", ec)) {
      const std::string name = entry.path().filename().string();
      if (entry.path().extension() == ".ply" && !written.count(name)) ++stale;
    }
    if (stale > 0) {
      LOG(WARNING) << (fs::path(out_dir) / "frames").string() << " holds " << stale
                   << " other .ply files (from an earlier run?); `banmo eval --pred` on this "
                      "folder would read them too";
    }
  }
  summary.articulate_seconds = timer.Seconds();

  const GridShape shape = ComputeGridShape(options.grid);
  // The sampled box in the files' (dataset) units.
  const double s = model.scene_scale();
  const Eigen::Vector3d lo = s * options.grid.bounds_min, hi = s * options.grid.bounds_max;
  std::ostringstream json;
  json.precision(17);
  json << "{\n"
       << "  \"resolution\": " << options.grid.resolution << ",\n"
       << "  \"cells\": [" << shape.cells.x() << ", " << shape.cells.y() << ", " << shape.cells.z()
       << "],\n"
       << "  \"bounds_min\": [" << lo.x() << ", " << lo.y() << ", " << lo.z() << "],\n"
       << "  \"bounds_max\": [" << hi.x() << ", " << hi.y() << ", " << hi.z() << "],\n"
       << "  \"scene_scale\": " << s << ",\n"
       << "  \"iso_level\": " << options.grid.iso_level << ",\n"
       << "  \"close_at_bounds\": " << (options.grid.close_at_bounds ? "true" : "false") << ",\n"
       << "  \"min_component_fraction\": " << options.min_component_fraction << ",\n"
       << "  \"color_video\": " << options.color_video << ",\n"
       << "  \"num_bones\": " << B << ",\n"
       << "  \"canonical_vertices\": " << summary.canonical_vertices << ",\n"
       << "  \"canonical_faces\": " << summary.canonical_faces << ",\n"
       << "  \"frames_written\": " << summary.frames_written << ",\n"
       << "  \"canonical_seconds\": " << summary.canonical_seconds << ",\n"
       << "  \"articulate_seconds\": " << summary.articulate_seconds << "\n"
       << "}\n";
  WriteFileAtomic((out / "extract.json").string(), json.str());
  staged.Commit();
  return summary;
}

Eigen::AlignedBox3d SurfaceBounds(const Model& model, const Eigen::AlignedBox3d& bounds,
                                  int resolution) {
  GridOptions grid;
  grid.resolution = resolution;
  grid.bounds_min = bounds.min();
  grid.bounds_max = bounds.max();
  const TriangleMesh mesh = KeepLargestComponent(MarchingCubes(ModelSdfFunction(model), grid));
  Eigen::AlignedBox3d box;  // empty
  for (int i = 0; i < mesh.NumVertices(); ++i) box.extend(Eigen::Vector3d(mesh.vertices.col(i)));
  return box;
}

Eigen::AlignedBox3d CanonicalBoundsFromSurface(const Model& model,
                                               const Eigen::AlignedBox3d& search) {
  const Eigen::AlignedBox3d surface = SurfaceBounds(model, search, 48);
  if (surface.isEmpty()) return search;
  const Eigen::Vector3d margin = 0.1 * surface.sizes() + Eigen::Vector3d::Constant(0.02);
  Eigen::AlignedBox3d box(surface.min() - margin, surface.max() + margin);
  box = box.intersection(
      Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-2.0), Eigen::Vector3d::Constant(2.0)));
  return box.isEmpty() ? search : box;
}

Eigen::AlignedBox3d ExtractionBounds(const Model& model) {
  const std::optional<Eigen::AlignedBox3d>& trained = model.canonical_bounds();
  if (trained) {
    // The model file refuses such boxes and the solver never sets one.
    CHECK(IsValidBox(*trained)) << "the model's canonical bounds are not a valid box: "
                                << trained->min().transpose() << " - "
                                << trained->max().transpose();
    return *trained;
  }
  return Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
}

}  // namespace banmo
