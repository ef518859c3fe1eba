// The loss terms of the objective (BANMo Sec. 3.4, Eq. 20, plus our
// regularisers) in one table. Everything keyed on a loss term derives from
// kLossTable: the config keys (stages[i].losses.<key>, optim/config.h), the
// default weights, the per-ray residual blocks the solver adds and the
// parameter blocks each reads, the progress-line names, and the tests'
// parameter lists. docs/equations.md maps each equation to its code.
//
// Adding a per-ray loss (README, "How to add a loss"): its functor header,
// one row here (before kCycle3d if the composite functor computes it), its call
// in RayCompositeFunctor (losses/ray_functors.h), and its test.
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>

namespace banmo {

// Per-ray terms first: the composite functor's terms (in the order of their
// residual rows), then the 3D cycle; then the regularisers, which are not
// per ray.
enum class LossTerm {
  kRgb = 0,
  kSilhouette,
  kFlow,
  kFeatureMatch,
  kCycle2d,
  kFeatureRender,
  kCycle3d,
  kEikonal,
  kBoneInside,
  kPoseSmoothness,
  kBoneJoint
};
inline constexpr int kNumLossTerms = 11;
// LossTerm values below kNumRayTerms are evaluated per ray (losses/ray_batch.h).
inline constexpr int kNumRayTerms = 7;
// ... and below kNumCompositeTerms by the composite functor (losses/ray_functors.h).
inline constexpr int kNumCompositeTerms = 6;

// Parameter blocks a ray's evaluation reads.
enum RayBlock {
  kBlockSdf = 0,
  kBlockColor,
  kBlockEmbedding,
  kBlockLogBeta,
  kBlockAppearance,
  kBlockRoot,           // root_delta of frame t
  kBlockBones,          // rest bones
  kBlockBonesT,         // bone transforms of frame t
  kBlockIntrinsics,     // intrinsics of the ray's video
  kBlockPartnerRoot,    // root_delta of the flow partner frame t'
  kBlockPartnerBonesT,  // bone transforms of frame t'
  kBlockDeltaSkin,      // MLP_Delta weights (delta skinning, Eq. 14)
  kBlockRestPoseCode,   // omega^* (forward warps' delta skinning)
  kBlockPoseCode,       // omega^t of frame t (backward warp's delta skinning)
  kNumRayBlocks
};

// A set of RayBlocks, one bit each; iterated in RayBlock order.
using RayBlockMask = uint32_t;
constexpr RayBlockMask MaskOf(std::initializer_list<RayBlock> blocks) {
  RayBlockMask mask = 0;
  for (RayBlock b : blocks) mask |= RayBlockMask{1} << b;
  return mask;
}
constexpr bool Contains(RayBlockMask mask, RayBlock block) {
  return (mask >> block) & RayBlockMask{1};
}

// Which rays a per-ray term applies to (Ray::HasTerm).
enum class RaySelect {
  kNotPerRay,          // regularisers
  kKnownMask,          // every ray with a mask value (object or background)
  kObject,             // object pixels (mask >= 0.5)
  kObjectWithFlow,     // object pixels with flow to another frame
  kObjectWithFeature,  // object pixels with a pixel feature
  kAll                 // every ray
};

struct LossTermInfo {
  LossTerm term;
  const char* key;        // YAML key and progress-line name
  const char* reference;  // where the paper defines it
  double default_weight;  // of a stage's config; 0 switches the term off
  int residuals;          // the functor's kNumResiduals (checked in losses/ray.cc); per
                          // ray, per sample when per_sample (regularisers: per item)
  bool per_sample;        // residual count scales with the ray's samples
  RaySelect rays;         // the rays it applies to
  RayBlockMask blocks;    // per-ray terms: the blocks its residual block reads
};

// The blocks a ray term reads when present; delta-skinning blocks only when
// the model has delta skinning, partner blocks only for flow rays.
inline constexpr RayBlockMask kWarpBlocks =
    MaskOf({kBlockRoot, kBlockBones, kBlockBonesT, kBlockIntrinsics, kBlockDeltaSkin});

inline constexpr std::array<LossTermInfo, kNumLossTerms> kLossTable = {{
    {LossTerm::kRgb, "rgb", "Sec. 3.4, L_rgb; Eq. 4", 1.0, 3, false, RaySelect::kObject,
     kWarpBlocks |
         MaskOf({kBlockSdf, kBlockColor, kBlockLogBeta, kBlockAppearance, kBlockPoseCode})},
    {LossTerm::kSilhouette, "silhouette", "Sec. 3.4, L_sil; Eq. 4", 1.0, 1, false,
     RaySelect::kKnownMask, kWarpBlocks | MaskOf({kBlockSdf, kBlockLogBeta, kBlockPoseCode})},
    {LossTerm::kFlow, "flow", "Eqs. 6-7, 16", 0.01, 2, false, RaySelect::kObjectWithFlow,
     kWarpBlocks | MaskOf({kBlockSdf, kBlockLogBeta, kBlockPartnerRoot, kBlockPartnerBonesT,
                           kBlockRestPoseCode, kBlockPoseCode})},
    {LossTerm::kFeatureMatch, "feature_match", "Eqs. 15, 17", 0.1, 3, false,
     RaySelect::kObjectWithFeature,
     kWarpBlocks | MaskOf({kBlockSdf, kBlockEmbedding, kBlockLogBeta, kBlockPoseCode})},
    {LossTerm::kCycle2d, "cycle_2d", "Eq. 18", 0.001, 2, false, RaySelect::kObjectWithFeature,
     kWarpBlocks | MaskOf({kBlockEmbedding, kBlockRestPoseCode})},
    // Off unless a stage weights it (configs written before it existed
    // keep their meaning).
    {LossTerm::kFeatureRender, "feature_render", "official code's frnd term; Eqs. 4, 15", 0.0, 16,
     false, RaySelect::kObjectWithFeature,
     kWarpBlocks | MaskOf({kBlockSdf, kBlockEmbedding, kBlockLogBeta, kBlockPoseCode})},
    {LossTerm::kCycle3d, "cycle_3d", "Eq. 19", 0.1, 3, true, RaySelect::kAll,
     kWarpBlocks | MaskOf({kBlockRestPoseCode, kBlockPoseCode})},
    {LossTerm::kEikonal, "eikonal", "Sec. 3.1 (VolSDF)", 0.01, 1, false, RaySelect::kNotPerRay, 0},
    {LossTerm::kBoneInside, "bone_inside", "regulariser (bones inside the surface)", 0.1, 1, false,
     RaySelect::kNotPerRay, 0},
    {LossTerm::kPoseSmoothness, "pose_smoothness", "regulariser (Sec. 3.2, Eq. 12)", 0.01, 6, false,
     RaySelect::kNotPerRay, 0},
    // Off unless a stage weights it (configs written before it existed
    // keep their meaning).
    {LossTerm::kBoneJoint, "bone_joint", "regulariser (neighbouring bones agree at their joint)",
     0.0, 3, false, RaySelect::kNotPerRay, 0},
}};

constexpr bool TableInOrder() {
  for (int t = 0; t < kNumLossTerms; ++t) {
    if (static_cast<int>(kLossTable[t].term) != t) return false;
  }
  return true;
}
static_assert(TableInOrder(), "kLossTable rows must follow LossTerm order");
constexpr bool RayTermsFirst() {
  for (int t = 0; t < kNumLossTerms; ++t) {
    if ((t < kNumRayTerms) != (kLossTable[t].rays != RaySelect::kNotPerRay)) return false;
  }
  return true;
}
static_assert(RayTermsFirst(), "per-ray terms come first, then the regularisers");

constexpr const LossTermInfo& LossInfo(LossTerm term) { return kLossTable[static_cast<int>(term)]; }
constexpr LossTerm RayTerm(int index) { return static_cast<LossTerm>(index); }
constexpr bool IsRayTerm(LossTerm term) { return static_cast<int>(term) < kNumRayTerms; }
// Every per-ray term, in table order (tests iterate over it).
constexpr std::array<LossTerm, kNumRayTerms> RayTerms() {
  std::array<LossTerm, kNumRayTerms> terms{};
  for (int t = 0; t < kNumRayTerms; ++t) terms[t] = RayTerm(t);
  return terms;
}

inline const char* LossTermName(LossTerm term) { return LossInfo(term).key; }
// Residuals of a per-ray term for a ray with `num_samples` samples.
inline int LossTermResiduals(LossTerm term, int num_samples) {
  const LossTermInfo& info = LossInfo(term);
  return info.per_sample ? info.residuals * num_samples : info.residuals;
}

}  // namespace banmo
