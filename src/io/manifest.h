// manifest.yaml of the dataset format (private to the io module; the format
// is documented in docs/dataset.md).
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "banmo/io/dataset.h"

namespace banmo::internal {

inline constexpr char kManifestName[] = "manifest.yaml";
inline constexpr char kFormatName[] = "banmo-dataset";
inline constexpr char kPosesInitName[] = "root_poses_init.txt";
inline constexpr char kPosesGtName[] = "root_poses_gt.txt";

struct ManifestVideo {
  std::string name;
  int frames = 0;
  int width = 0;
  int height = 0;
  Eigen::Vector4d intrinsics = Eigen::Vector4d::Zero();  // fx, fy, cx, cy
  std::optional<Eigen::Vector4d> intrinsics_gt;          // the true ones, if given
  VideoContents present;
};

struct Manifest {
  int version = kDatasetFormatVersion;
  int feature_dim = kFeatureDim;
  std::vector<int> flow_gaps;  // sorted, unique, positive
  FlowEncoding flow_encoding = FlowEncoding::kKittiPng16;
  DepthEncoding depth_encoding = DepthEncoding::kPng16;
  double depth_unit = 0.0;  // only meaningful with 16-bit depth
  std::vector<ManifestVideo> videos;
};

// Parses and validates `path`; throws InputError naming the file and key.
Manifest ReadManifest(const std::string& path);
// YAML text of the manifest.
std::string EmitManifest(const Manifest& manifest);
// Throws InputError (naming `where`) if the name is not usable as a folder.
void CheckVideoName(const std::string& name, const std::string& where);
// Throws InputError (naming `where`) on bad intrinsics for the given size.
void CheckIntrinsics(const Eigen::Vector4d& intrinsics, int width, int height,
                     const std::string& where);

// Finishes off an AddVideosToDataset that was killed (dataset_add.cc): for
// each staging folder `<root>.add-<pid>-<n>` beside the dataset whose
// process is gone, the add is rolled back (video folders it moved into the
// dataset but the manifest does not list are removed) or, if the manifest
// already lists its videos, only the staging folder is removed; temporary
// manifests (manifest.yaml.tmp.*) of a killed write are removed too.
// Returns a note of what was done ("" if nothing). Called by LoadDataset
// and AddVideosToDataset, so `check`, `solve` and `prepare --add` recover.
std::string RecoverInterruptedAdd(const std::string& root);

const char* FlowEncodingName(FlowEncoding e);
const char* DepthEncodingName(DepthEncoding e);

}  // namespace banmo::internal
