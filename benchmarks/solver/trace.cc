#include "trace.h"

#include <sys/resource.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "banmo/util/error.h"

namespace banmo::bench {
namespace {

struct Segment {
  std::string key;
  int index = -2;  // -2: no [..], -1: [*], >= 0: [i]
};

std::vector<Segment> ParsePath(const std::string& path, const std::string& what) {
  std::vector<Segment> out;
  std::stringstream ss(path);
  std::string item;
  while (std::getline(ss, item, '.')) {
    Segment seg;
    const size_t open = item.find('[');
    if (open == std::string::npos) {
      seg.key = item;
    } else {
      if (item.back() != ']' || open == 0) {
        ThrowInputError(what, ": expected key or key[i] or key[*], got '", item, "'");
      }
      seg.key = item.substr(0, open);
      const std::string inside = item.substr(open + 1, item.size() - open - 2);
      if (inside == "*") {
        seg.index = -1;
      } else {
        char* end = nullptr;
        const long i = std::strtol(inside.c_str(), &end, 10);
        if (inside.empty() || *end != '\0' || i < 0 || i > 100000) {
          ThrowInputError(what, ": bad list index '[", inside, "]'");
        }
        seg.index = static_cast<int>(i);
      }
    }
    if (seg.key.empty()) ThrowInputError(what, ": empty key in path '", path, "'");
    out.push_back(seg);
  }
  if (out.empty()) ThrowInputError(what, ": empty path");
  return out;
}

// Sets path[k..] below `node` (a map) to `value`.
void SetPath(YAML::Node node, const std::vector<Segment>& path, size_t k, const YAML::Node& value,
             const std::string& what) {
  const Segment& seg = path[k];
  const bool last = k + 1 == path.size();
  if (!node.IsMap()) ThrowInputError(what, ": '", seg.key, "' is below a value that is not a map");
  if (seg.index == -2) {
    if (last) {
      node[seg.key] = value;
      return;
    }
    if (!node[seg.key] || node[seg.key].IsNull()) node[seg.key] = YAML::Node(YAML::NodeType::Map);
    SetPath(node[seg.key], path, k + 1, value, what);
    return;
  }
  YAML::Node list = node[seg.key];
  if (!list || !list.IsSequence()) {
    ThrowInputError(what, ": '", seg.key, "' is not a list in the config");
  }
  const int n = static_cast<int>(list.size());
  if (seg.index >= n) {
    ThrowInputError(what, ": '", seg.key, "' has ", n, " element(s), index ", seg.index);
  }
  for (int i = 0; i < n; ++i) {
    if (seg.index >= 0 && i != seg.index) continue;
    if (last) {
      list[i] = value;
    } else {
      if (list[i].IsNull()) list[i] = YAML::Node(YAML::NodeType::Map);
      SetPath(list[i], path, k + 1, value, what);
    }
  }
}

std::string Num(double v) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}

}  // namespace

std::string ApplyOverrides(const std::string& yaml_text, const std::vector<std::string>& overrides,
                           const std::string& source) {
  if (overrides.empty()) return yaml_text;
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    ThrowInputError(source, ": invalid YAML: ", e.what());
  }
  if (!root.IsMap()) ThrowInputError(source, ": expected a map at the top level");
  for (const std::string& o : overrides) {
    const std::string what = "override '" + o + "' of " + source;
    const size_t eq = o.find('=');
    if (eq == std::string::npos || eq == 0) ThrowInputError(what, ": expected path=value");
    YAML::Node value;
    try {
      value = YAML::Load(o.substr(eq + 1));
    } catch (const YAML::Exception& e) {
      ThrowInputError(what, ": the value is not valid YAML: ", e.what());
    }
    SetPath(root, ParsePath(o.substr(0, eq), what), 0, value, what);
  }
  YAML::Emitter out;
  out << root;
  return std::string(out.c_str()) + "\n";
}

SolverConfig ParseConfigWithOverrides(const std::string& yaml_text,
                                      const std::vector<std::string>& overrides,
                                      const std::string& source) {
  const std::string label = overrides.empty() ? source : source + " with overrides";
  return ParseSolverConfig(ApplyOverrides(yaml_text, overrides, source), label);
}

std::string FirstNonFiniteBlock(const Model& model) {
  // Model::ForEachBlock is non-const; the caller's model must not change, so
  // walk the const accessors in the same order.
  auto bad = [](const double* d, int n) {
    for (int k = 0; k < n; ++k) {
      if (!std::isfinite(d[k])) return true;
    }
    return false;
  };
  if (bad(model.sdf(), model.sdf_size())) return "sdf";
  if (bad(model.color(), model.color_size())) return "color";
  if (bad(model.embedding(), model.embedding_size())) return "embedding";
  if (bad(model.log_beta(), 1)) return "log_beta";
  if (bad(model.bones(), model.bones_size())) return "bones";
  for (int v = 0; v < model.num_videos(); ++v) {
    const VideoParameters& video = model.video(v);
    const std::string prefix = "video" + std::to_string(v) + "/";
    if (bad(video.intrinsics.data(), 4)) return prefix + "intrinsics";
    if (bad(video.appearance.data(), static_cast<int>(video.appearance.size()))) {
      return prefix + "appearance";
    }
    for (size_t t = 0; t < video.frames.size(); ++t) {
      const FrameParameters& f = video.frames[t];
      const std::string fp = prefix + "frame" + std::to_string(t) + "/";
      if (bad(f.root_delta.data(), kPoseSize)) return fp + "root_delta";
      if (bad(f.root_init.data(), kPoseSize)) return fp + "root_init";
      if (bad(f.bones_t.data(), static_cast<int>(f.bones_t.size()))) return fp + "bones_t";
    }
  }
  return "";
}

const std::vector<std::string>& TraceLossTerms() {
  static const std::vector<std::string> terms = {"rgb",           "silhouette", "flow",
                                                 "feature_match", "cycle_2d",   "cycle_3d"};
  return terms;
}

std::string TraceCsvHeader() {
  std::string h =
      "config,scene,kind,stage,stage_name,batch,total_batches,solve_seconds,cpu_seconds,"
      "wall_seconds,trace_seconds,loss_total";
  for (const std::string& t : TraceLossTerms()) h += ",loss_" + t;
  h += ",params_finite,losses_finite,nonfinite_what,resolution,mesh_vertices,eval_frames,"
       "chamfer_cm,fscore_1,fscore_2,fscore_5,root_rot_mean_deg,root_rot_p90_deg\n";
  return h;
}

std::string TraceCsvLine(const TraceRow& r) {
  std::ostringstream os;
  double total = 0.0;
  for (const auto& [name, value] : r.losses) total += value;
  os << r.config << ',' << r.scene << ',' << r.kind << ',' << r.stage << ',' << r.stage_name << ','
     << r.batch << ',' << r.total_batches << ',' << Num(r.solve_seconds) << ','
     << Num(r.cpu_seconds) << ',' << Num(r.wall_seconds) << ',' << Num(r.trace_seconds) << ','
     << (r.losses.empty() ? "nan" : Num(total));
  for (const std::string& t : TraceLossTerms()) {
    auto it = r.losses.find(t);
    os << ',' << (it == r.losses.end() ? std::string("0") : Num(it->second));
  }
  os << ',' << (r.params_finite ? 1 : 0) << ',' << (r.losses_finite ? 1 : 0) << ','
     << r.nonfinite_what << ',' << r.resolution << ',' << r.mesh_vertices << ',' << r.eval_frames
     << ',' << Num(r.chamfer_cm) << ',' << Num(r.fscore[0]) << ',' << Num(r.fscore[1]) << ','
     << Num(r.fscore[2]) << ',' << Num(r.root_rot_mean_deg) << ',' << Num(r.root_rot_p90_deg)
     << '\n';
  return os.str();
}

double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + 1e-6 * u.ru_utime.tv_usec + u.ru_stime.tv_sec +
         1e-6 * u.ru_stime.tv_usec;
}

}  // namespace banmo::bench
