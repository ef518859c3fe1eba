#include "banmo/gltf/export.h"

// Debian's libtinygltf-dev is a shared library (stb and the JSON parser
// compiled in): no TINYGLTF_IMPLEMENTATION anywhere in this project.
#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <numeric>
#include <sstream>

#include "banmo/geometry/se3.h"
#include "banmo/gltf/validate.h"
#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/timer.h"

namespace banmo {

void GltfExportOptions::Check() const {
  extract.Check();
  if (!(fps > 0) || !std::isfinite(fps)) ThrowInputError("fps: expected > 0, got ", fps);
  for (size_t i = 0; i < video_names.size(); ++i) {
    if (video_names[i].empty()) ThrowInputError("video_names[", i, "]: empty name");
  }
}

void TopInfluences(const Eigen::MatrixXd& weights, int k, Eigen::MatrixXi* joints,
                   Eigen::MatrixXd* out_weights) {
  CHECK_GE(k, 1);
  const int B = static_cast<int>(weights.rows());
  const Eigen::Index n = weights.cols();
  joints->setZero(k, n);
  out_weights->setZero(k, n);
  const int kept = std::min(k, B);
  std::vector<int> order(B);
  for (Eigen::Index i = 0; i < n; ++i) {
    std::iota(order.begin(), order.end(), 0);
    // Largest first; ties by bone index so the result is deterministic.
    std::partial_sort(order.begin(), order.begin() + kept, order.end(), [&](int a, int b) {
      return weights(a, i) > weights(b, i) || (weights(a, i) == weights(b, i) && a < b);
    });
    double sum = 0;
    for (int j = 0; j < kept; ++j) sum += weights(order[j], i);
    for (int j = 0; j < kept; ++j) {
      (*joints)(j, i) = order[j];
      (*out_weights)(j, i) = sum > 0 ? weights(order[j], i) / sum : (j == 0 ? 1.0 : 0.0);
    }
  }
}

namespace {

// A = rotation by 180 degrees about x: OpenCV camera axes (y down, z forward)
// to glTF's (y up, camera looking along -z).
const Eigen::Matrix3d& OpenCvToGltf() {
  static const Eigen::Matrix3d a = Eigen::Vector3d(1, -1, -1).asDiagonal();
  return a;
}

// Appends typed data to the single buffer, one buffer view per accessor.
class BufferWriter {
 public:
  explicit BufferWriter(tinygltf::Model* m) : m_(m) {
    if (m_->buffers.empty()) m_->buffers.emplace_back();
  }

  // count elements of `components` values each; min/max stored if asked.
  int AddFloat(const std::vector<float>& data, int type, int components, int target, bool bounds) {
    const size_t count = data.size() / components;
    const int view = AddView(data.data(), data.size() * sizeof(float), target);
    tinygltf::Accessor a;
    a.bufferView = view;
    a.byteOffset = 0;
    a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    a.count = count;
    a.type = type;
    if (bounds) {
      a.minValues.assign(components, std::numeric_limits<double>::infinity());
      a.maxValues.assign(components, -std::numeric_limits<double>::infinity());
      for (size_t i = 0; i < count; ++i) {
        for (int c = 0; c < components; ++c) {
          const double v = data[i * components + c];
          a.minValues[c] = std::min(a.minValues[c], v);
          a.maxValues[c] = std::max(a.maxValues[c], v);
        }
      }
    }
    m_->accessors.push_back(a);
    return static_cast<int>(m_->accessors.size()) - 1;
  }

  template <typename Int>
  int AddInts(const std::vector<Int>& data, int component_type, int type, int components,
              int target) {
    const int view = AddView(data.data(), data.size() * sizeof(Int), target);
    tinygltf::Accessor a;
    a.bufferView = view;
    a.byteOffset = 0;
    a.componentType = component_type;
    a.count = data.size() / components;
    a.type = type;
    m_->accessors.push_back(a);
    return static_cast<int>(m_->accessors.size()) - 1;
  }

 private:
  int AddView(const void* bytes, size_t size, int target) {
    std::vector<unsigned char>& buffer = m_->buffers[0].data;
    buffer.resize((buffer.size() + 3) / 4 * 4, 0);  // 4-byte alignment
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = buffer.size();
    v.byteLength = size;
    v.target = target;
    const auto* p = static_cast<const unsigned char*>(bytes);
    buffer.insert(buffer.end(), p, p + size);
    m_->bufferViews.push_back(v);
    return static_cast<int>(m_->bufferViews.size()) - 1;
  }

  tinygltf::Model* m_;
};

// Rest frame R_b of bone b (canonical_from_bone): centre C_b, orientation V_b.
Eigen::Isometry3d RestBoneFrame(const double* bone) {
  Eigen::Quaterniond q(bone[kBoneQw], bone[kBoneQw + 1], bone[kBoneQw + 2], bone[kBoneQw + 3]);
  q.normalize();
  Eigen::Isometry3d r = Eigen::Isometry3d::Identity();
  r.linear() = q.toRotationMatrix();
  r.translation() =
      Eigen::Vector3d(bone[kBoneCenter], bone[kBoneCenter + 1], bone[kBoneCenter + 2]);
  return r;
}

// Unit quaternion of a rotation as glTF [x, y, z, w], sign-aligned with
// `previous` (if given) so consecutive keys are on the same hemisphere.
Eigen::Vector4d GltfQuaternion(const Eigen::Matrix3d& rotation, const Eigen::Vector4d* previous) {
  Eigen::Quaterniond q(rotation);
  q.normalize();
  Eigen::Vector4d xyzw(q.x(), q.y(), q.z(), q.w());
  if (previous != nullptr && xyzw.dot(*previous) < 0) xyzw = -xyzw;
  return xyzw;
}

// x with its translation in dataset units (rotations do not change): the
// model's lengths times its scene scale s.
Eigen::Isometry3d InDatasetUnits(Eigen::Isometry3d x, double s) {
  x.translation() *= s;
  return x;
}

void SetTrs(const Eigen::Isometry3d& t, tinygltf::Node* node) {
  const Eigen::Vector4d q = GltfQuaternion(t.linear(), nullptr);
  node->rotation = {q[0], q[1], q[2], q[3]};
  node->translation = {t.translation().x(), t.translation().y(), t.translation().z()};
}

// Area-weighted vertex normals (unit; +z of the input frame for isolated or
// degenerate vertices).
Eigen::Matrix3Xd VertexNormals(const TriangleMesh& mesh) {
  Eigen::Matrix3Xd n = Eigen::Matrix3Xd::Zero(3, mesh.NumVertices());
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.faces(0, f));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.faces(1, f));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.faces(2, f));
    const Eigen::Vector3d area2 = (b - a).cross(c - a);
    for (int k = 0; k < 3; ++k) n.col(mesh.faces(k, f)) += area2;
  }
  for (int i = 0; i < n.cols(); ++i) {
    const double len = n.col(i).norm();
    if (len > 0 && std::isfinite(len)) {
      n.col(i) /= len;
    } else {
      n.col(i) = Eigen::Vector3d::UnitZ();
    }
  }
  return n;
}

std::string VideoName(const GltfExportOptions& options, int v, int num_videos) {
  if (!options.video_names.empty()) return options.video_names[v];
  int digits = 2;
  for (int n = num_videos - 1; n >= 100; n /= 10) ++digits;
  std::ostringstream name;
  name << "video" << std::setw(digits) << std::setfill('0') << v;
  return name.str();
}

bool AllFinite(const double* data, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(data[i])) return false;
  }
  return true;
}

// Throws InputError unless the mesh, the names and the model's transforms can
// be exported.
void CheckExportInputs(const Model& model, const TriangleMesh& canonical,
                       const GltfExportOptions& options) {
  const int V = canonical.NumVertices();
  const int F = canonical.NumFaces();
  if (V == 0 || F == 0) ThrowInputError("glTF export: the canonical mesh is empty");
  if (!canonical.vertices.allFinite()) {
    ThrowInputError("glTF export: the canonical mesh has non-finite vertices");
  }
  if (canonical.faces.minCoeff() < 0 || canonical.faces.maxCoeff() >= V) {
    ThrowInputError("glTF export: the canonical mesh has face indices out of range");
  }
  if (!options.video_names.empty() &&
      static_cast<int>(options.video_names.size()) != model.num_videos()) {
    ThrowInputError("video_names: ", options.video_names.size(), " names for ", model.num_videos(),
                    " videos");
  }
  if (!AllFinite(model.bones(), static_cast<size_t>(model.bones_size()))) {
    ThrowInputError("glTF export: the model's rest bones have non-finite values");
  }
  for (int v = 0; v < model.num_videos(); ++v) {
    for (int t = 0; t < static_cast<int>(model.video(v).frames.size()); ++t) {
      const FrameParameters& f = model.frame(v, t);
      const Pose g = model.RootPose(v, t);
      if (!g.allFinite() || !AllFinite(f.bones_t.data(), f.bones_t.size())) {
        ThrowInputError("glTF export: video ", v, " frame ", t,
                        ": root pose or bone transforms are not finite");
      }
    }
  }
}

// The mesh's triangle primitive: indices, positions and normals in the
// scene's world frame (A s X*), and linear vertex colours if asked for.
tinygltf::Primitive MeshPrimitive(const TriangleMesh& canonical, double s,
                                  const GltfExportOptions& options, BufferWriter* writer) {
  const int V = canonical.NumVertices();
  const int F = canonical.NumFaces();
  const Eigen::Matrix3d& A = OpenCvToGltf();
  std::vector<float> positions(3 * static_cast<size_t>(V)), normals(positions.size());
  const Eigen::Matrix3Xd n_canonical = VertexNormals(canonical);
  for (int i = 0; i < V; ++i) {
    const Eigen::Vector3d x = A * (s * canonical.vertices.col(i));
    const Eigen::Vector3d n = (A * n_canonical.col(i)).normalized();
    for (int c = 0; c < 3; ++c) {
      positions[3 * i + c] = static_cast<float>(x[c]);
      normals[3 * i + c] = static_cast<float>(n[c]);
    }
  }
  std::vector<uint32_t> indices(3 * static_cast<size_t>(F));
  for (int f = 0; f < F; ++f) {
    for (int k = 0; k < 3; ++k) indices[3 * f + k] = static_cast<uint32_t>(canonical.faces(k, f));
  }
  tinygltf::Primitive prim;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  prim.indices = writer->AddInts(indices, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                 TINYGLTF_TYPE_SCALAR, 1, TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  prim.attributes["POSITION"] = writer->AddFloat(positions, TINYGLTF_TYPE_VEC3, 3,
                                                 TINYGLTF_TARGET_ARRAY_BUFFER, /*bounds=*/true);
  prim.attributes["NORMAL"] =
      writer->AddFloat(normals, TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  if (options.vertex_colors && canonical.HasColors()) {
    std::vector<float> colors(3 * static_cast<size_t>(V));
    for (int i = 0; i < V; ++i) {
      for (int c = 0; c < 3; ++c) {
        colors[3 * i + c] = static_cast<float>(std::pow(canonical.colors(c, i) / 255.0, 2.2));
      }
    }
    prim.attributes["COLOR_0"] =
        writer->AddFloat(colors, TINYGLTF_TYPE_VEC3, 3, TINYGLTF_TARGET_ARRAY_BUFFER, false);
  }
  return prim;
}

// JOINTS_0 / WEIGHTS_0 of the primitive: each vertex's top 4 skinning weights
// (summing to 1 within a float ulp); the largest weight dropped goes into
// summary->max_dropped_weight.
void AddSkinAttributes(const Model& model, const TriangleMesh& canonical, BufferWriter* writer,
                       tinygltf::Primitive* prim, GltfExportSummary* summary) {
  const int V = canonical.NumVertices();
  const int B = model.num_bones();
  const Eigen::MatrixXd weights = SkinningWeightsAt(model, canonical.vertices);
  Eigen::MatrixXi top_joints;
  Eigen::MatrixXd top_weights;
  TopInfluences(weights, kGltfInfluences, &top_joints, &top_weights);
  std::vector<uint16_t> joints(4 * static_cast<size_t>(V));
  std::vector<float> w(4 * static_cast<size_t>(V));
  for (int i = 0; i < V; ++i) {
    if (B > kGltfInfluences) {
      double kept = 0;
      for (int k = 0; k < kGltfInfluences; ++k) kept += weights(top_joints(k, i), i);
      summary->max_dropped_weight = std::max(summary->max_dropped_weight, 1.0 - kept);
    }
    float f[4];
    for (int k = 0; k < 4; ++k) {
      joints[4 * i + k] = static_cast<uint16_t>(top_joints(k, i));
      f[k] = static_cast<float>(top_weights(k, i));
    }
    // Float rounding leaves the sum within a few 1e-8 of 1; move the
    // remainder onto the largest weight (slot 0) so it is within one float
    // ulp of 1 (1.2e-7).
    const double sum = static_cast<double>(f[0]) + f[1] + f[2] + f[3];
    f[0] = static_cast<float>(f[0] + (1.0 - sum));
    for (int k = 0; k < 4; ++k) w[4 * i + k] = f[k];
    // A slot of weight 0 (fewer bones than slots, or a weight that
    // underflowed: sharp bones far away) names joint 0, as the Khronos
    // validator asks (ACCESSOR_JOINTS_USED_ZERO_WEIGHT); slot 0 holds the
    // largest weight, never 0.
    for (int k = 1; k < 4; ++k) {
      if (f[k] == 0.0f) joints[4 * i + k] = 0;
    }
  }
  summary->max_dropped_weight = std::max(0.0, summary->max_dropped_weight);
  prim->attributes["JOINTS_0"] =
      writer->AddInts(joints, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT, TINYGLTF_TYPE_VEC4, 4,
                      TINYGLTF_TARGET_ARRAY_BUFFER);
  prim->attributes["WEIGHTS_0"] =
      writer->AddFloat(w, TINYGLTF_TYPE_VEC4, 4, TINYGLTF_TARGET_ARRAY_BUFFER, false);
}

// Nodes: 0 axis conversion, 1 root, 2.. bones, last mesh.
constexpr int kAxisNode = 0, kRootNode = 1, kFirstBoneNode = 2;

// The skin: one joint per bone node, inverse bind matrices of the rest frames
// in the world frame (A R_b).
tinygltf::Skin BoneSkin(const std::vector<Eigen::Isometry3d>& rest, BufferWriter* writer) {
  const int B = static_cast<int>(rest.size());
  const Eigen::Matrix3d& A = OpenCvToGltf();
  tinygltf::Skin skin;
  skin.name = "bones";
  skin.skeleton = kRootNode;
  std::vector<float> ibm(16 * static_cast<size_t>(B));
  for (int b = 0; b < B; ++b) {
    skin.joints.push_back(kFirstBoneNode + b);
    Eigen::Matrix4d bind = Eigen::Matrix4d::Identity();  // world_from_joint at rest = A R_b
    bind.topLeftCorner<3, 3>() = A * rest[b].linear();
    bind.topRightCorner<3, 1>() = A * rest[b].translation();
    Eigen::Matrix4d inverse = Eigen::Matrix4d::Identity();
    inverse.topLeftCorner<3, 3>() = bind.topLeftCorner<3, 3>().transpose();
    inverse.topRightCorner<3, 1>() =
        -bind.topLeftCorner<3, 3>().transpose() * bind.topRightCorner<3, 1>();
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) ibm[16 * b + 4 * c + r] = static_cast<float>(inverse(r, c));
    }
    // Exact affine last row (the validator checks it).
    ibm[16 * b + 3] = ibm[16 * b + 7] = ibm[16 * b + 11] = 0.0f;
    ibm[16 * b + 15] = 1.0f;
  }
  skin.inverseBindMatrices =
      writer->AddFloat(ibm, TINYGLTF_TYPE_MAT4, 16, /*target=*/0, /*bounds=*/false);
  return skin;
}

// The node tree, the skin (with bones) and the scene; returns the bones' rest
// frames in dataset units.
std::vector<Eigen::Isometry3d> AddNodesAndScene(const Model& model, double s, BufferWriter* writer,
                                                tinygltf::Model* m) {
  const int B = model.num_bones();
  const int mesh_node = kFirstBoneNode + B;
  m->nodes.resize(3 + B);
  m->nodes[kAxisNode].name = "opencv_to_gltf";
  m->nodes[kAxisNode].rotation = {1, 0, 0, 0};  // 180 deg about x, [x, y, z, w]
  m->nodes[kAxisNode].children = {kRootNode};
  m->nodes[kRootNode].name = "root";
  m->nodes[mesh_node].name = "mesh";
  m->nodes[mesh_node].mesh = 0;
  std::vector<Eigen::Isometry3d> rest(B);
  for (int b = 0; b < B; ++b) {
    rest[b] = InDatasetUnits(RestBoneFrame(model.bones() + kBoneSize * b), s);
    tinygltf::Node& node = m->nodes[kFirstBoneNode + b];
    node.name = "bone_" + std::to_string(b);
    SetTrs(rest[b], &node);
    m->nodes[kRootNode].children.push_back(kFirstBoneNode + b);
  }
  tinygltf::Scene scene;
  scene.name = "banmo";
  scene.nodes = {kAxisNode};
  if (B > 0) {
    // Skinned: the mesh node is a top-level node without transform.
    scene.nodes.push_back(mesh_node);
    m->nodes[mesh_node].skin = 0;
    m->skins.push_back(BoneSkin(rest, writer));
  } else {
    // Rigid: the mesh node under "root" undoes A, so that
    // world = A G^t A^{-1} (A X*) = A G^t X* and the rest pose is A X*.
    m->nodes[kRootNode].children.push_back(mesh_node);
    m->nodes[mesh_node].rotation = {1, 0, 0, 0};
  }
  m->scenes.push_back(scene);
  m->defaultScene = 0;
  return rest;
}

// Samplers and channels animating node `node` of `anim`: its local transform
// local(t) at the T key times of accessor `input`.
void AddAnimatedNode(int node, int T, int input, const std::string& interpolation,
                     const std::function<Eigen::Isometry3d(int t)>& local, BufferWriter* writer,
                     tinygltf::Animation* anim) {
  std::vector<float> translation(3 * static_cast<size_t>(T)), rotation(4 * static_cast<size_t>(T));
  Eigen::Vector4d previous;
  for (int t = 0; t < T; ++t) {
    const Eigen::Isometry3d x = local(t);
    const Eigen::Vector4d q = GltfQuaternion(x.linear(), t > 0 ? &previous : nullptr);
    previous = q;
    for (int c = 0; c < 3; ++c) translation[3 * t + c] = static_cast<float>(x.translation()[c]);
    // Normalise in float so the stored quaternion is unit to float rounding.
    Eigen::Vector4f qf = q.cast<float>();
    qf /= qf.norm();
    for (int c = 0; c < 4; ++c) rotation[4 * t + c] = qf[c];
  }
  for (const char* path : {"translation", "rotation"}) {
    const bool is_t = std::strcmp(path, "translation") == 0;
    tinygltf::AnimationSampler sampler;
    sampler.input = input;
    sampler.output = is_t ? writer->AddFloat(translation, TINYGLTF_TYPE_VEC3, 3, 0, false)
                          : writer->AddFloat(rotation, TINYGLTF_TYPE_VEC4, 4, 0, false);
    sampler.interpolation = interpolation;
    anim->samplers.push_back(sampler);
    tinygltf::AnimationChannel channel;
    channel.sampler = static_cast<int>(anim->samplers.size()) - 1;
    channel.target_node = node;
    channel.target_path = path;
    anim->channels.push_back(channel);
  }
}

// Video v's animation: the root's and every bone's transform per frame, keys
// at t / fps. `rest`: the bones' rest frames in dataset units.
tinygltf::Animation VideoAnimation(const Model& model, int v, const GltfExportOptions& options,
                                   const std::vector<Eigen::Isometry3d>& rest, double s,
                                   BufferWriter* writer) {
  const int T = static_cast<int>(model.video(v).frames.size());
  const std::string interpolation =
      options.interpolation == GltfInterpolation::kLinear ? "LINEAR" : "STEP";
  tinygltf::Animation anim;
  anim.name = VideoName(options, v, model.num_videos());
  std::vector<float> times(T);
  for (int t = 0; t < T; ++t) times[t] = static_cast<float>(t / options.fps);
  for (int t = 1; t < T; ++t) {
    if (!(times[t] > times[t - 1])) {
      ThrowInputError("fps: ", options.fps, " too large: key times of ", T,
                      " frames collide in float32");
    }
  }
  const int input = writer->AddFloat(times, TINYGLTF_TYPE_SCALAR, 1, 0, /*bounds=*/true);
  AddAnimatedNode(
      kRootNode, T, input, interpolation,
      [&](int t) { return InDatasetUnits(IsometryFromPose(model.RootPose(v, t).data()), s); },
      writer, &anim);
  for (int b = 0; b < static_cast<int>(rest.size()); ++b) {
    AddAnimatedNode(
        kFirstBoneNode + b, T, input, interpolation,
        [&, b](int t) {
          return InDatasetUnits(IsometryFromPose(model.frame(v, t).bones_t.data() + kPoseSize * b),
                                s) *
                 rest[b];
        },
        writer, &anim);
  }
  return anim;
}

}  // namespace

GltfExportSummary BuildGltf(const Model& model, const TriangleMesh& canonical,
                            const GltfExportOptions& options, tinygltf::Model* out) {
  options.Check();
  Timer timer;
  CheckExportInputs(model, canonical, options);
  GltfExportSummary summary;
  summary.vertices = canonical.NumVertices();
  summary.faces = canonical.NumFaces();
  summary.joints = model.num_bones();
  const double s = model.scene_scale();  // the file is in dataset units

  *out = tinygltf::Model();
  tinygltf::Model& m = *out;
  m.asset.version = "2.0";
  m.asset.generator = "banmo-ceres banmo export";
  BufferWriter writer(&m);

  tinygltf::Primitive prim = MeshPrimitive(canonical, s, options, &writer);
  if (model.num_bones() > 0) AddSkinAttributes(model, canonical, &writer, &prim, &summary);
  tinygltf::Material material;
  material.name = "vertex_colors";
  material.pbrMetallicRoughness.baseColorFactor = {1, 1, 1, 1};
  material.pbrMetallicRoughness.metallicFactor = 0.0;  // glTF's default 1 looks like dark metal
  material.pbrMetallicRoughness.roughnessFactor = 1.0;
  m.materials.push_back(material);
  prim.material = 0;
  tinygltf::Mesh mesh;
  mesh.name = "canonical";
  mesh.primitives.push_back(prim);
  m.meshes.push_back(mesh);

  const std::vector<Eigen::Isometry3d> rest = AddNodesAndScene(model, s, &writer, &m);
  // Animations: one per video.
  for (int v = 0; v < model.num_videos(); ++v) {
    const int T = static_cast<int>(model.video(v).frames.size());
    if (T == 0) continue;
    m.animations.push_back(VideoAnimation(model, v, options, rest, s, &writer));
    ++summary.animations;
    summary.keyframes += T;
  }

  CheckGltfOrThrow(m, "glTF export");
  summary.build_seconds = timer.Seconds();
  return summary;
}

std::size_t WriteGltf(const tinygltf::Model& gltf, const std::string& path, bool binary) {
  tinygltf::TinyGLTF writer;
  std::ostringstream stream;
  if (!writer.WriteGltfSceneToStream(&gltf, stream, /*prettyPrint=*/!binary, binary)) {
    ThrowInputError(path, ": tinygltf could not serialise the glTF document");
  }
  const std::string bytes = stream.str();
  WriteFileAtomic(path, bytes);
  return bytes.size();
}

void ReadGltf(const std::string& path, tinygltf::Model* out) {
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  const bool glb = path.size() >= 4 && path.compare(path.size() - 4, 4, ".glb") == 0;
  const bool ok = glb ? loader.LoadBinaryFromFile(out, &err, &warn, path)
                      : loader.LoadASCIIFromFile(out, &err, &warn, path);
  if (!ok) ThrowInputError(path, ": cannot read glTF: ", err.empty() ? "unknown error" : err);
}

GltfExportSummary ExportGltf(const Model& model, const GltfExportOptions& options,
                             const std::string& path,
                             const std::function<void(const std::string&)>& progress) {
  options.Check();
  Timer timer;
  const TriangleMesh canonical = ExtractCanonicalMesh(model, options.extract);
  if (canonical.NumFaces() == 0) {
    ThrowInputError("the model's SDF has no zero level set inside the bounds [",
                    options.extract.grid.bounds_min.transpose(), "] - [",
                    options.extract.grid.bounds_max.transpose(), "]: nothing to export");
  }
  const double mesh_seconds = timer.Seconds();
  if (progress) {
    std::ostringstream os;
    os << "canonical mesh: " << canonical.NumVertices() << " vertices, " << canonical.NumFaces()
       << " faces (" << mesh_seconds << " s)";
    progress(os.str());
  }
  tinygltf::Model gltf;
  GltfExportSummary summary = BuildGltf(model, canonical, options, &gltf);
  summary.mesh_seconds = mesh_seconds;
  if (progress) {
    std::ostringstream os;
    os << "glTF built and validated: " << summary.joints << " joints, " << summary.animations
       << " animations, " << summary.keyframes << " keyframes (" << summary.build_seconds << " s)";
    progress(os.str());
  }
  timer.Reset();
  const bool text = path.size() >= 5 && path.compare(path.size() - 5, 5, ".gltf") == 0;
  summary.bytes = WriteGltf(gltf, path, /*binary=*/!text);
  summary.write_seconds = timer.Seconds();
  return summary;
}

}  // namespace banmo
