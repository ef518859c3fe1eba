#include "manifest.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

#include "banmo/io/codecs.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"
#include "banmo/util/yaml.h"

namespace banmo::internal {
namespace {

// Names of the `present` entries. rgb, mask and root_poses_init are required.
constexpr const char* kRequiredData[] = {"rgb", "mask", "root_poses_init"};
constexpr const char* kOptionalData[] = {"flow",    "features",      "depth",
                                         "gt_mesh", "root_poses_gt", "mask_gt"};

}  // namespace

const char* FlowEncodingName(FlowEncoding e) { return EnumName(e); }
const char* DepthEncodingName(DepthEncoding e) { return EnumName(e); }

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

// The top-level keys other than `videos`.
void ReadHeader(const YamlNode& root, Manifest* m) {
  const std::string& path = root.source();
  const std::string format = root.Required("format").As<std::string>();
  if (format != kFormatName) {
    ThrowInputError(path, ": key 'format' is '", format, "', expected '", kFormatName, "'");
  }
  root.ReadRequired("version", &m->version);
  if (m->version != kDatasetFormatVersion) {
    ThrowInputError(path, ": unsupported format version ", m->version, " (this program reads ",
                    kDatasetFormatVersion, ")");
  }
  root.ReadRequired("feature_dim", &m->feature_dim);
  if (m->feature_dim != kFeatureDim) {
    ThrowInputError(path, ": key 'feature_dim' is ", m->feature_dim, ", expected ", kFeatureDim);
  }
  const YamlNode gaps = root.Required("flow_gaps");
  if (!gaps.IsSequence()) gaps.TypeError("a list of positive integers");
  for (std::size_t i = 0; i < gaps.size(); ++i) {
    const int gap = gaps[i].As<int>("a positive integer");
    if (gap <= 0 || gap >= 100000) gaps[i].Fail("gap ", gap, " is not in [1, 99999]");
    m->flow_gaps.push_back(gap);
  }
  std::sort(m->flow_gaps.begin(), m->flow_gaps.end());
  if (std::adjacent_find(m->flow_gaps.begin(), m->flow_gaps.end()) != m->flow_gaps.end()) {
    gaps.Fail("duplicate gap");
  }
  root.ReadIfPresent("flow_encoding", &m->flow_encoding);
  root.ReadIfPresent("depth_encoding", &m->depth_encoding);
  if (root.Has("depth_unit")) {
    m->depth_unit = root["depth_unit"].As<double>("a positive number");
    // 1e-9 .. 1e3 per step of a 16-bit PNG: nanometres to a 65 km range.
    if (!(m->depth_unit >= 1e-9 && m->depth_unit <= 1e3)) {
      ThrowInputError(path, ": key 'depth_unit' is ", m->depth_unit,
                      ", expected a number in [1e-9, 1e3] (scene units per step of a 16-bit "
                      "depth PNG)");
    }
  }
}

// The `present` list of a video entry.
VideoContents ReadPresent(const YamlNode& present) {
  if (!present.IsSequence()) present.TypeError("a list");
  std::set<std::string> items;
  for (std::size_t i = 0; i < present.size(); ++i) {
    const std::string item = present[i].As<std::string>("a name");
    const bool known = std::any_of(std::begin(kRequiredData), std::end(kRequiredData),
                                   [&](const char* n) { return item == n; }) ||
                       std::any_of(std::begin(kOptionalData), std::end(kOptionalData),
                                   [&](const char* n) { return item == n; });
    if (!known) {
      present[i].Fail("unknown entry '", item,
                      "' (expected rgb, mask, root_poses_init, flow, features, depth, gt_mesh, "
                      "root_poses_gt, mask_gt)");
    }
    items.insert(item);
  }
  for (const char* req : kRequiredData) {
    if (items.count(req) == 0) present.Fail("must list '", req, "'");
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

// [fx, fy, cx, cy] at `node`, checked against the image size.
Eigen::Vector4d ReadIntrinsics(const YamlNode& node, int width, int height) {
  if (!node.IsSequence() || node.size() != 4) node.TypeError("[fx, fy, cx, cy]");
  Eigen::Vector4d k;
  for (int j = 0; j < 4; ++j) k[j] = node[j].As<double>("a finite number");
  CheckIntrinsics(k, width, height,
                  node.source() + ": key '" + node.path() + "'" + node.LineNote());
  return k;
}

// Entry `v` of `videos` (a map); `names` collects the names seen so far.
ManifestVideo ReadVideoEntry(const YamlNode& v, const Manifest& m, std::set<std::string>* names) {
  const std::set<std::string> keys = {"name",       "frames",        "width",  "height",
                                      "intrinsics", "intrinsics_gt", "present"};
  v.CheckKeys(keys, YamlNode::ChoicesNote(keys));
  ManifestVideo mv;
  v.ReadRequired("name", &mv.name);
  const YamlNode name = v["name"];
  CheckVideoName(mv.name, name.source() + ": key '" + name.path() + "'" + name.LineNote());
  if (!names->insert(mv.name).second) name.Fail("duplicate video name '", mv.name, "'");
  mv.frames = v.Required("frames").As<int>("a positive integer");
  mv.width = v.Required("width").As<int>("a positive integer");
  mv.height = v.Required("height").As<int>("a positive integer");
  if (mv.frames <= 0 || mv.frames > 100000) {
    v["frames"].Fail(mv.frames, " frames in video '", mv.name, "', expected 1..100000");
  }
  if (mv.width <= 0 || mv.height <= 0 || mv.width > kMaxImageSide || mv.height > kMaxImageSide ||
      static_cast<long>(mv.width) * mv.height > kMaxFramePixels) {
    v.Fail("video '", mv.name, "': image size ", mv.width, "x", mv.height,
           " is beyond the limit (width and height in 1..", kMaxImageSide, ", at most ",
           kMaxFramePixels, " pixels; docs/robustness.md)");
  }
  mv.intrinsics = ReadIntrinsics(v.Required("intrinsics"), mv.width, mv.height);
  if (v.Has("intrinsics_gt")) {
    mv.intrinsics_gt = ReadIntrinsics(v["intrinsics_gt"], mv.width, mv.height);
  }
  const YamlNode present = v.Required("present");
  mv.present = ReadPresent(present);
  if (mv.present.flow && m.flow_gaps.empty()) {
    present.Fail("lists 'flow' but flow_gaps is empty");
  }
  if (mv.present.depth && m.depth_encoding == DepthEncoding::kPng16 && m.depth_unit <= 0) {
    ThrowInputError(v.source(), ": key 'depth_unit' is required with 16-bit PNG depth (", v.path(),
                    " ('", mv.name, "') has depth)");
  }
  return mv;
}

}  // namespace

Manifest ReadManifest(const std::string& path) {
  const YamlNode root = YamlNode::Parse(
      ReadRegularFile(path, kMaxTextFileBytes, " (the manifest; every dataset folder has one)"),
      path);
  const std::set<std::string> keys = {"format",        "version",        "feature_dim", "flow_gaps",
                                      "flow_encoding", "depth_encoding", "depth_unit",  "videos"};
  root.CheckKeys(keys, YamlNode::ChoicesNote(keys));
  Manifest m;
  ReadHeader(root, &m);
  const YamlNode videos = root.Required("videos");
  if (!videos.IsSequence() || videos.size() == 0) videos.TypeError("a non-empty list");
  std::set<std::string> names;
  long pixels = 0;
  for (std::size_t i = 0; i < videos.size(); ++i) {
    m.videos.push_back(ReadVideoEntry(videos[i], m, &names));
    const ManifestVideo& mv = m.videos.back();
    pixels += static_cast<long>(mv.frames) * mv.width * mv.height;
    if (pixels > kMaxDatasetPixels) {
      ThrowInputError(path, ": key 'videos': ", i + 1, " video(s) declare ", pixels,
                      " pixels (frames x width x height), beyond the limit of ", kMaxDatasetPixels,
                      " per dataset (docs/robustness.md)", videos[i].LineNote());
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
