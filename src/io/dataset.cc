// Small shared pieces of the dataset format: Frame/Dataset helpers, file
// names, pose files.
#include "banmo/io/dataset.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "banmo/util/atomic_file.h"
#include "banmo/util/error.h"
#include "banmo/util/input_file.h"

namespace banmo {

const FlowField* Frame::FlowForGap(int gap) const {
  for (const FlowField& f : flows) {
    if (f.gap == gap) return &f;
  }
  return nullptr;
}

int Dataset::NumFrames() const {
  int n = 0;
  for (const Video& v : videos) n += static_cast<int>(v.frames.size());
  return n;
}

int Dataset::NumSkippedFrames() const {
  int n = 0;
  for (const Video& v : videos) {
    for (const Frame& f : v.frames) n += f.skip ? 1 : 0;
  }
  return n;
}

bool Dataset::HasPixelFeatures() const {
  for (const Video& v : videos) {
    for (const Frame& f : v.frames) {
      if (!f.skip && !f.features.empty()) return true;
    }
  }
  return false;
}

std::uintmax_t DirectoryBytes(const std::string& dir) {
  std::uintmax_t total = 0;
  std::error_code ec;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
       !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file(ec)) total += it->file_size(ec);
  }
  return total;
}

std::string FrameFileName(int index, const std::string& extension) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%05d.", index);
  return buffer + extension;
}

std::vector<Pose> ReadPoseFile(const std::string& path, int expected_lines) {
  std::istringstream in(ReadRegularFile(path, kMaxTextFileBytes, " (the pose file)"));
  std::vector<Pose> poses;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line[0] == '#') continue;
    std::istringstream ss(line);
    std::vector<double> values;
    std::string token;
    while (ss >> token) {
      char* end = nullptr;
      const double value = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') {
        ThrowInputError(path, ":", line_number, ": '", token,
                        "' is not a number (expected 'qw qx qy qz tx ty tz')");
      }
      values.push_back(value);
    }
    if (values.size() != kPoseSize) {
      ThrowInputError(path, ":", line_number, ": expected 7 numbers 'qw qx qy qz tx ty tz', found ",
                      values.size());
    }
    Pose pose;
    for (int i = 0; i < kPoseSize; ++i) pose[i] = values[i];
    if (!pose.allFinite()) ThrowInputError(path, ":", line_number, ": non-finite pose value");
    if (pose.tail<3>().cwiseAbs().maxCoeff() > kMaxPoseTranslation) {
      ThrowInputError(path, ":", line_number, ": translation (tx ty tz) beyond +-",
                      kMaxPoseTranslation, " (docs/robustness.md)");
    }
    const double norm = pose.head<4>().norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      ThrowInputError(path, ":", line_number, ": quaternion (qw qx qy qz) has norm ", norm,
                      ", expected 1 +- 1e-3");
    }
    // Normalise, but keep already unit quaternions bit-exact (round trips).
    if (std::abs(norm - 1.0) > 1e-12) pose.head<4>() /= norm;
    poses.push_back(pose);
  }
  if (expected_lines >= 0 && static_cast<int>(poses.size()) != expected_lines) {
    ThrowInputError(path, ": expected ", expected_lines, " pose lines (one per frame), found ",
                    poses.size());
  }
  return poses;
}

void WritePoseFile(const std::string& path, const std::vector<Pose>& poses,
                   const std::string& comment) {
  std::string text = "# qw qx qy qz tx ty tz (camera_from_root), one line per frame\n";
  if (!comment.empty()) {
    std::istringstream lines(comment);
    std::string line;
    while (std::getline(lines, line)) text += "# " + line + "\n";
  }
  char buffer[256];
  for (const Pose& p : poses) {
    std::snprintf(buffer, sizeof(buffer), "%.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", p[0], p[1],
                  p[2], p[3], p[4], p[5], p[6]);
    text += buffer;
  }
  WriteFileAtomic(path, text);
}

}  // namespace banmo
