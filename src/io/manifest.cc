#include "manifest.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

#include "banmo/io/codecs.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"

namespace banmo::internal {
namespace {

// Names of the `present` entries. rgb, mask and root_poses_init are required.
constexpr const char* kRequiredData[] = {"rgb", "mask", "root_poses_init"};
constexpr const char* kOptionalData[] = {"flow",    "features",      "depth",
                                         "gt_mesh", "root_poses_gt", "mask_gt"};

std::string Where(const std::string& path, const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.line < 0) return path;
  return path + ":" + std::to_string(mark.line + 1);
}

void CheckKeys(const YAML::Node& map, const std::string& path, const std::string& context,
               const std::set<std::string>& allowed) {
  if (!map.IsMap()) ThrowInputError(Where(path, map), ": ", context, " must be a mapping");
  std::set<std::string> seen;
  for (const auto& kv : map) {
    const std::string key = kv.first.Scalar();
    if (!seen.insert(key).second) {
      // yaml-cpp keeps the first of repeated keys; which one was meant is unknown.
      ThrowInputError(Where(path, kv.first), ": duplicate key '", key, "' in ", context);
    }
    if (allowed.count(key) == 0) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      ThrowInputError(Where(path, kv.first), ": unknown key '", key, "' in ", context,
                      " (expected one of: ", list, ")");
    }
  }
}

const YAML::Node Required(const YAML::Node& map, const std::string& key, const std::string& path,
                          const std::string& context) {
  const YAML::Node node = map[key];
  if (!node) ThrowInputError(path, ": missing key '", key, "' in ", context);
  return node;
}

template <typename T>
T As(const YAML::Node& node, const std::string& path, const std::string& key,
     const char* expected) {
  try {
    if (!node.IsScalar()) throw YAML::Exception(node.Mark(), "not a scalar");
    return node.as<T>();
  } catch (const YAML::Exception&) {
    ThrowInputError(Where(path, node), ": key '", key, "': expected ", expected);
  }
}

}  // namespace

const char* FlowEncodingName(FlowEncoding e) {
  return e == FlowEncoding::kKittiPng16 ? "kitti_png16" : "npy";
}
const char* DepthEncodingName(DepthEncoding e) {
  return e == DepthEncoding::kPng16 ? "png16" : "npy";
}

void CheckVideoName(const std::string& name, const std::string& where) {
  const bool ok =
      !name.empty() && name != "." && name != ".." && name.size() <= 128 &&
      std::all_of(name.begin(), name.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
      });
  if (!ok || name == kManifestName) {
    ThrowInputError(where, ": bad video name '", name,
                    "' (expected 1-128 characters of [A-Za-z0-9_.-], not '.', '..' or '",
                    kManifestName, "')");
  }
}

void CheckIntrinsics(const Eigen::Vector4d& k, int width, int height, const std::string& where) {
  const bool ok = k.allFinite() && k[0] > 0 && k[1] > 0 && k[2] >= 0 && k[2] <= width &&
                  k[3] >= 0 && k[3] <= height;
  if (!ok) {
    ThrowInputError(where, ": bad intrinsics [", k[0], ", ", k[1], ", ", k[2], ", ", k[3],
                    "]: expected finite [fx, fy, cx, cy] with fx, fy > 0 and the principal "
                    "point inside the ",
                    width, "x", height, " image");
  }
}

namespace {

FlowEncoding ReadFlowEncoding(const YAML::Node& node, const std::string& path) {
  const std::string e = As<std::string>(node, path, "flow_encoding", "kitti_png16 or npy");
  if (e == "kitti_png16") return FlowEncoding::kKittiPng16;
  if (e == "npy") return FlowEncoding::kNpy;
  ThrowInputError(path, ": key 'flow_encoding' is '", e, "', expected kitti_png16 or npy");
}

DepthEncoding ReadDepthEncoding(const YAML::Node& node, const std::string& path) {
  const std::string e = As<std::string>(node, path, "depth_encoding", "png16 or npy");
  if (e == "png16") return DepthEncoding::kPng16;
  if (e == "npy") return DepthEncoding::kNpy;
  ThrowInputError(path, ": key 'depth_encoding' is '", e, "', expected png16 or npy");
}

// The top-level keys other than `videos`.
void ReadHeader(const YAML::Node& root, const std::string& path, Manifest* m) {
  const std::string top = "the manifest";
  const std::string format =
      As<std::string>(Required(root, "format", path, top), path, "format", "a string");
  if (format != kFormatName) {
    ThrowInputError(path, ": key 'format' is '", format, "', expected '", kFormatName, "'");
  }
  m->version = As<int>(Required(root, "version", path, top), path, "version", "an integer");
  if (m->version != kDatasetFormatVersion) {
    ThrowInputError(path, ": unsupported format version ", m->version, " (this program reads ",
                    kDatasetFormatVersion, ")");
  }
  m->feature_dim =
      As<int>(Required(root, "feature_dim", path, top), path, "feature_dim", "an integer");
  if (m->feature_dim != kFeatureDim) {
    ThrowInputError(path, ": key 'feature_dim' is ", m->feature_dim, ", expected ", kFeatureDim);
  }
  const YAML::Node gaps = Required(root, "flow_gaps", path, top);
  if (!gaps.IsSequence()) {
    ThrowInputError(Where(path, gaps), ": key 'flow_gaps': expected a list of positive integers");
  }
  for (const auto& g : gaps) {
    const int gap = As<int>(g, path, "flow_gaps", "a list of positive integers");
    if (gap <= 0 || gap >= 100000) {
      ThrowInputError(Where(path, g), ": key 'flow_gaps': gap ", gap, " is not in [1, 99999]");
    }
    m->flow_gaps.push_back(gap);
  }
  std::sort(m->flow_gaps.begin(), m->flow_gaps.end());
  if (std::adjacent_find(m->flow_gaps.begin(), m->flow_gaps.end()) != m->flow_gaps.end()) {
    ThrowInputError(Where(path, gaps), ": key 'flow_gaps': duplicate gap");
  }
  if (root["flow_encoding"]) m->flow_encoding = ReadFlowEncoding(root["flow_encoding"], path);
  if (root["depth_encoding"]) m->depth_encoding = ReadDepthEncoding(root["depth_encoding"], path);
  if (root["depth_unit"]) {
    m->depth_unit = As<double>(root["depth_unit"], path, "depth_unit", "a positive number");
    // 1e-9 .. 1e3 per step of a 16-bit PNG: nanometres to a 65 km range.
    if (!(m->depth_unit >= 1e-9 && m->depth_unit <= 1e3)) {
      ThrowInputError(path, ": key 'depth_unit' is ", m->depth_unit,
                      ", expected a number in [1e-9, 1e3] (scene units per step of a 16-bit "
                      "depth PNG)");
    }
  }
}

// The `present` list of a video entry.
VideoContents ReadPresent(const YAML::Node& present, const std::string& path,
                          const std::string& vctx) {
  if (!present.IsSequence()) {
    ThrowInputError(Where(path, present), ": ", vctx, ".present: expected a list");
  }
  std::set<std::string> items;
  for (const auto& p : present) {
    const std::string item = As<std::string>(p, path, vctx + ".present", "a list of names");
    const bool known = std::any_of(std::begin(kRequiredData), std::end(kRequiredData),
                                   [&](const char* n) { return item == n; }) ||
                       std::any_of(std::begin(kOptionalData), std::end(kOptionalData),
                                   [&](const char* n) { return item == n; });
    if (!known) {
      ThrowInputError(Where(path, p), ": unknown entry '", item, "' in ", vctx,
                      ".present (expected rgb, mask, root_poses_init, flow, features, depth, "
                      "gt_mesh, root_poses_gt, mask_gt)");
    }
    items.insert(item);
  }
  for (const char* req : kRequiredData) {
    if (items.count(req) == 0) {
      ThrowInputError(Where(path, present), ": ", vctx, ".present must list '", req, "'");
    }
  }
  VideoContents c;
  c.flow = items.count("flow") > 0;
  c.features = items.count("features") > 0;
  c.depth = items.count("depth") > 0;
  c.gt_mesh = items.count("gt_mesh") > 0;
  c.root_poses_gt = items.count("root_poses_gt") > 0;
  c.mask_gt = items.count("mask_gt") > 0;
  return c;
}

// Entry `i` of `videos`; `names` collects the names seen so far.
ManifestVideo ReadVideoEntry(const YAML::Node& v, std::size_t i, const std::string& path,
                             const Manifest& m, std::set<std::string>* names) {
  const std::string ctx = "videos[" + std::to_string(i) + "]";
  CheckKeys(v, path, ctx,
            {"name", "frames", "width", "height", "intrinsics", "intrinsics_gt", "present"});
  ManifestVideo mv;
  mv.name = As<std::string>(Required(v, "name", path, ctx), path, ctx + ".name", "a string");
  CheckVideoName(mv.name, Where(path, v["name"]));
  if (!names->insert(mv.name).second) {
    ThrowInputError(Where(path, v["name"]), ": duplicate video name '", mv.name, "'");
  }
  const std::string vctx = ctx + " ('" + mv.name + "')";
  mv.frames =
      As<int>(Required(v, "frames", path, vctx), path, vctx + ".frames", "a positive integer");
  mv.width = As<int>(Required(v, "width", path, vctx), path, vctx + ".width", "a positive integer");
  mv.height =
      As<int>(Required(v, "height", path, vctx), path, vctx + ".height", "a positive integer");
  if (mv.frames <= 0 || mv.frames > 100000) {
    ThrowInputError(Where(path, v["frames"]), ": ", vctx, ".frames = ", mv.frames,
                    ", expected 1..100000");
  }
  if (mv.width <= 0 || mv.height <= 0 || mv.width > kMaxImageSide || mv.height > kMaxImageSide ||
      static_cast<long>(mv.width) * mv.height > kMaxFramePixels) {
    ThrowInputError(Where(path, v), ": ", vctx, ": image size ", mv.width, "x", mv.height,
                    " is beyond the limit (width and height in 1..", kMaxImageSide, ", at most ",
                    kMaxFramePixels, " pixels; docs/robustness.md)");
  }
  const YAML::Node k = Required(v, "intrinsics", path, vctx);
  if (!k.IsSequence() || k.size() != 4) {
    ThrowInputError(Where(path, k), ": ", vctx, ".intrinsics: expected [fx, fy, cx, cy]");
  }
  for (int j = 0; j < 4; ++j) {
    mv.intrinsics[j] = As<double>(k[j], path, vctx + ".intrinsics", "4 numbers");
  }
  CheckIntrinsics(mv.intrinsics, mv.width, mv.height, Where(path, k) + ": " + vctx + ".intrinsics");
  if (const YAML::Node kg = v["intrinsics_gt"]) {
    if (!kg.IsSequence() || kg.size() != 4) {
      ThrowInputError(Where(path, kg), ": ", vctx, ".intrinsics_gt: expected [fx, fy, cx, cy]");
    }
    Eigen::Vector4d gt;
    for (int j = 0; j < 4; ++j)
      gt[j] = As<double>(kg[j], path, vctx + ".intrinsics_gt", "4 numbers");
    CheckIntrinsics(gt, mv.width, mv.height, Where(path, kg) + ": " + vctx + ".intrinsics_gt");
    mv.intrinsics_gt = gt;
  }
  const YAML::Node present = Required(v, "present", path, vctx);
  mv.present = ReadPresent(present, path, vctx);
  if (mv.present.flow && m.flow_gaps.empty()) {
    ThrowInputError(Where(path, present), ": ", vctx,
                    ".present lists 'flow' but flow_gaps is empty");
  }
  if (mv.present.depth && m.depth_encoding == DepthEncoding::kPng16 && m.depth_unit <= 0) {
    ThrowInputError(path, ": key 'depth_unit' is required with 16-bit PNG depth (", vctx,
                    " has depth)");
  }
  return mv;
}

}  // namespace

Manifest ReadManifest(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::Load(
        ReadRegularFile(path, kMaxTextFileBytes, " (the manifest; every dataset folder has one)"));
  } catch (const YAML::Exception& e) {
    ThrowInputError(path, ": YAML syntax error at line ", e.mark.line + 1, ": ", e.msg);
  }
  const std::string top = "the manifest";
  CheckKeys(root, path, top,
            {"format", "version", "feature_dim", "flow_gaps", "flow_encoding", "depth_encoding",
             "depth_unit", "videos"});
  Manifest m;
  ReadHeader(root, path, &m);
  const YAML::Node videos = Required(root, "videos", path, top);
  if (!videos.IsSequence() || videos.size() == 0) {
    ThrowInputError(Where(path, videos), ": key 'videos': expected a non-empty list");
  }
  std::set<std::string> names;
  long pixels = 0;
  for (std::size_t i = 0; i < videos.size(); ++i) {
    m.videos.push_back(ReadVideoEntry(videos[i], i, path, m, &names));
    const ManifestVideo& mv = m.videos.back();
    pixels += static_cast<long>(mv.frames) * mv.width * mv.height;
    if (pixels > kMaxDatasetPixels) {
      ThrowInputError(Where(path, videos[i]), ": key 'videos': ", i + 1, " video(s) declare ",
                      pixels, " pixels (frames x width x height), beyond the limit of ",
                      kMaxDatasetPixels, " per dataset (docs/robustness.md)");
    }
  }
  return m;
}

std::string EmitManifest(const Manifest& m) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormatName;
  out << YAML::Key << "version" << YAML::Value << m.version;
  out << YAML::Key << "feature_dim" << YAML::Value << m.feature_dim;
  out << YAML::Key << "flow_gaps" << YAML::Value << YAML::Flow << m.flow_gaps;
  out << YAML::Key << "flow_encoding" << YAML::Value << FlowEncodingName(m.flow_encoding);
  out << YAML::Key << "depth_encoding" << YAML::Value << DepthEncodingName(m.depth_encoding);
  if (m.depth_unit > 0) out << YAML::Key << "depth_unit" << YAML::Value << m.depth_unit;
  out << YAML::Key << "videos" << YAML::Value << YAML::BeginSeq;
  for (const ManifestVideo& v : m.videos) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << v.name;
    out << YAML::Key << "frames" << YAML::Value << v.frames;
    out << YAML::Key << "width" << YAML::Value << v.width;
    out << YAML::Key << "height" << YAML::Value << v.height;
    out << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginSeq
        << v.intrinsics[0] << v.intrinsics[1] << v.intrinsics[2] << v.intrinsics[3] << YAML::EndSeq;
    if (v.intrinsics_gt) {
      const Eigen::Vector4d& k = *v.intrinsics_gt;
      out << YAML::Key << "intrinsics_gt" << YAML::Value << YAML::Flow << YAML::BeginSeq << k[0]
          << k[1] << k[2] << k[3] << YAML::EndSeq;
    }
    std::vector<std::string> present = {"rgb", "mask", "root_poses_init"};
    if (v.present.flow) present.push_back("flow");
    if (v.present.features) present.push_back("features");
    if (v.present.depth) present.push_back("depth");
    if (v.present.gt_mesh) present.push_back("gt_mesh");
    if (v.present.root_poses_gt) present.push_back("root_poses_gt");
    if (v.present.mask_gt) present.push_back("mask_gt");
    out << YAML::Key << "present" << YAML::Value << YAML::Flow << present;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace banmo::internal
