#include "stage_problem.h"

#include <algorithm>

#include "banmo/deform/articulated_manifold.h"
#include "banmo/deform/bones.h"
#include "banmo/geometry/pose_manifold.h"
#include "banmo/losses/regularizers.h"
#include "banmo/util/logging.h"

namespace banmo {

std::unique_ptr<ceres::LossFunction> MakeRobustLoss(const RobustLossConfig& c) {
  switch (c.type) {
    case RobustLossType::kNone:
      return nullptr;
    case RobustLossType::kHuber:
      return std::make_unique<ceres::HuberLoss>(c.scale);
    case RobustLossType::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(c.scale);
    case RobustLossType::kSoftL1:
      return std::make_unique<ceres::SoftLOneLoss>(c.scale);
    case RobustLossType::kArctan:
      return std::make_unique<ceres::ArctanLoss>(c.scale);
    case RobustLossType::kTolerant:
      return std::make_unique<ceres::TolerantLoss>(c.scale, c.scale);
  }
  return nullptr;
}

namespace {

RayBatchOptions BatchOptions(const StageConfig& stage) {
  RayBatchOptions o;
  o.weights = stage.losses.RayWeights();
  o.match_top_k = stage.sampling.match_top_k;
  o.feature_render_embedding_only = stage.losses.feature_render_embedding_only;
  o.matcher.exact = true;  // deterministic (FLANN's trees are randomised)
  // Adam (and the alternate rule's Adam on the stage's batch; its pose
  // solves have batches of their own, without the 3D cycle) evaluates the
  // minibatch once, where SetRays left it.
  o.hold_cycle_tau = stage.step_rule == StepRule::kLm;
  return o;
}

}  // namespace

StageProblem::StageProblem(Model* model, const StageConfig& stage,
                           const ParameterGroupSet& extra_constant)
    : model_(*model), stage_(stage), batch_(model, BatchOptions(stage)) {
  ceres::Problem::Options options;
  options.evaluation_callback = &batch_;
  options.enable_fast_removal = true;
  options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_ = std::make_unique<ceres::Problem>(options);
  configured_constant_ = extra_constant;
  for (ParameterGroup g : stage.constant) configured_constant_.Insert(g);
  constant_ = configured_constant_;
  for (int t = 0; t < kNumLossTerms; ++t) robust_[t] = MakeRobustLoss(stage.losses.terms[t].robust);
  for (int t = 0; t < kNumRayTerms; ++t) ray_robust_[t] = robust_[t].get();
  AddModelBlocks();
}

StageProblem::~StageProblem() { ClearMinibatch(); }

void StageProblem::AddBlock(ParameterGroup group, double* data, int size,
                            std::unique_ptr<ceres::Manifold> manifold) {
  if (size == 0) return;
  problem_->AddParameterBlock(data, size, manifold.release());
  Blocks(group).push_back(data);
  group_of_[data] = group;
}

void StageProblem::AddModelBlocks() {
  using G = ParameterGroup;
  for (auto& blocks : groups_) blocks.clear();
  group_of_.clear();
  Model& m = model_;
  const int B = m.num_bones();
  AddBlock(G::kSdf, m.sdf(), m.sdf_size(), nullptr);
  AddBlock(G::kColor, m.color(), m.color_size(), nullptr);
  AddBlock(G::kEmbedding, m.embedding(), m.embedding_size(), nullptr);
  AddBlock(G::kLogBeta, m.log_beta(), 1, nullptr);
  if (stage_.bone_steps_articulated && B > 0) {
    if (!bone_tree_) bone_tree_ = std::make_unique<BoneTree>();
    *bone_tree_ = MakeBoneTree(m.bones(), B);
  }
  if (B > 0) {
    AddBlock(G::kBones, m.bones(), m.bones_size(),
             MakeStackedQuaternionBlockManifold(B, kBoneSize, kBoneQw));
  }
  if (m.has_delta_skinning()) {
    AddBlock(G::kDeltaSkinning, m.delta_skinning_params(), m.delta_skinning_size(), nullptr);
    AddBlock(G::kDeltaSkinning, m.rest_pose_code(), m.pose_code_size(), nullptr);
  }
  for (int v = 0; v < m.num_videos(); ++v) {
    AddBlock(G::kIntrinsics, m.video(v).intrinsics.data(), kIntrinsicsSize, nullptr);
    AddBlock(G::kAppearance, m.video(v).appearance.data(), m.appearance_size(), nullptr);
    for (size_t t = 0; t < m.video(v).frames.size(); ++t) {
      FrameParameters& f = m.frame(v, t);
      AddBlock(G::kRoot, f.root_delta.data(), kPoseSize, MakePoseManifold());
      if (B > 0) {
        std::unique_ptr<ceres::Manifold> manifold;
        if (stage_.bone_steps_articulated) {
          manifold = MakeArticulatedBoneManifold(B, bone_tree_.get());
        } else if (stage_.bone_steps_about_centres) {
          manifold = MakeStackedPivotPoseManifold(B, m.bones(), kBoneSize, kBoneCenter);
        } else {
          manifold = MakeStackedPoseManifold(B);
        }
        AddBlock(G::kBonesT, f.bones_t.data(), kPoseSize * B, std::move(manifold));
      }
      if (m.has_delta_skinning()) {
        AddBlock(G::kPoseCode, f.pose_code.data(), m.pose_code_size(), nullptr);
      }
    }
  }
  Restore();
}

void StageProblem::RemoveAllBlocks() {
  ClearMinibatch();
  std::vector<double*> blocks;
  problem_->GetParameterBlocks(&blocks);
  for (double* p : blocks) problem_->RemoveParameterBlock(p);
}

void StageProblem::HoldGroup(ParameterGroup g, bool hold) {
  hold = hold || configured_constant_.Contains(g);
  if (hold) {
    constant_.Insert(g);
  } else {
    constant_.Erase(g);
  }
  for (double* p : Blocks(g)) {
    if (hold) {
      problem_->SetParameterBlockConstant(p);
    } else {
      problem_->SetParameterBlockVariable(p);
    }
  }
}

bool StageProblem::FrozenAfterReinit(int batch_index) const {
  const ScheduleConfig& schedule = stage_.schedule;
  if (!(schedule.freeze_after_reinit > 0.0)) return false;
  // From each batch the solver re-initialises at (Solver::RunSchedules).
  const int length = stage_.BatchAt(schedule.freeze_after_reinit);
  for (double at : schedule.bone_reinit_at) {
    const int start = stage_.BatchAt(at);
    if (batch_index >= start && batch_index < start + length) return true;
  }
  return false;
}

void StageProblem::ScheduleGroups(int batch_index) {
  using G = ParameterGroup;
  const double fraction = static_cast<double>(batch_index) / std::max(1, stage_.batches);
  const bool frozen = model_.num_bones() > 0 && FrozenAfterReinit(batch_index);
  if (stage_.schedule.freeze_after_reinit > 0.0) {
    for (G g : {G::kSdf, G::kColor, G::kEmbedding, G::kLogBeta, G::kAppearance}) {
      HoldGroup(g, frozen);
    }
  }
  if (stage_.schedule.root_free_from > 0.0 || stage_.schedule.freeze_after_reinit > 0.0) {
    HoldGroup(G::kRoot, frozen || fraction < stage_.schedule.root_free_from);
  }
  if (!model_.has_delta_skinning()) return;
  const bool free = fraction >= stage_.schedule.delta_skinning_from;
  for (ParameterGroup g : {ParameterGroup::kDeltaSkinning, ParameterGroup::kPoseCode}) {
    HoldGroup(g, !free);
  }
  batch_.SetDeltaSkinning(
      (free && !configured_constant_.Contains(ParameterGroup::kDeltaSkinning)) ||
      model_.DeltaSkinningIsNonZero());
}

void StageProblem::ClearMinibatch() {
  for (ceres::ResidualBlockId id : batch_blocks_) problem_->RemoveResidualBlock(id);
  batch_blocks_.clear();
  regularizer_blocks_.clear();
}

void StageProblem::AddRegularizer(std::unique_ptr<ceres::CostFunction> cost,
                                  ceres::LossFunction* loss, const std::vector<double*>& blocks) {
  batch_blocks_.push_back(problem_->AddResidualBlock(cost.release(), loss, blocks));
  regularizer_blocks_.push_back(batch_blocks_.back());
}

void StageProblem::SetMinibatch(std::vector<Ray> rays, const Eigen::Matrix3Xd& match_grid,
                                const Eigen::AlignedBox3d& bounds, std::mt19937* rng) {
  CHECK(batch_blocks_.empty()) << "ClearMinibatch first";
  Model& model = model_;
  const int B = model.num_bones();
  const LossesConfig& losses = stage_.losses;
  // The articulated steps' joints follow the rest bones (re-initialisations,
  // Adam steps), fixed for the batch: its gradient and its step see the same
  // tree, and a resumed run rebuilds it from the same bones.
  if (bone_tree_) *bone_tree_ = MakeBoneTree(model.bones(), B);
  batch_.SetMatchGrid(match_grid);
  batch_.SetRays(std::move(rays));
  used_.clear();
  for (int r = 0; r < batch_.num_rays(); ++r) {
    for (LossTerm term : RayTerms()) {
      if (!batch_.rays()[r].HasTerm(term, batch_.options().weights)) continue;
      std::vector<double*> blocks = batch_.TermParameterBlocks(r, term);
      used_.insert(blocks.begin(), blocks.end());
      batch_blocks_.push_back(problem_->AddResidualBlock(batch_.MakeCostFunction(r, term).release(),
                                                         robust_[static_cast<int>(term)].get(),
                                                         blocks));
    }
  }
  auto robust = [&](LossTerm term) { return robust_[static_cast<int>(term)].get(); };
  const double eikonal = losses[LossTerm::kEikonal].weight;
  if (eikonal > 0 && stage_.sampling.eikonal_points > 0) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    Eigen::Matrix3Xd points(3, stage_.sampling.eikonal_points);
    for (int i = 0; i < points.cols(); ++i) {
      for (int k = 0; k < 3; ++k) {
        points(k, i) = bounds.min()[k] + unit(*rng) * bounds.sizes()[k];
      }
    }
    AddRegularizer(MakeEikonalCostFunction(model.field(), points, eikonal),
                   robust(LossTerm::kEikonal), {model.sdf()});
  }
  const double inside = losses[LossTerm::kBoneInside].weight;
  if (B > 0 && inside > 0) {
    AddRegularizer(MakeBoneInsideCostFunction(model.field(), B, losses.bone_inside_margin, inside),
                   robust(LossTerm::kBoneInside), {model.sdf(), model.bones()});
  }
  // The batch's frames, for the per-frame regularisers below.
  std::set<std::pair<int, int>> frames;
  for (const Ray& ray : batch_.rays()) frames.insert({ray.video, ray.frame});
  const double w = losses[LossTerm::kPoseSmoothness].weight;
  if (w > 0) {
    for (const auto& [v, t] : frames) {
      if (t + 1 >= static_cast<int>(model.video(v).frames.size())) continue;
      FrameParameters& a = model.frame(v, t);
      FrameParameters& b = model.frame(v, t + 1);
      AddRegularizer(MakeRootSmoothnessCostFunction(a.root_init, b.root_init, w, w),
                     robust(LossTerm::kPoseSmoothness), {a.root_delta.data(), b.root_delta.data()});
      used_.insert(b.root_delta.data());
      if (B > 0) {
        AddRegularizer(MakeBoneSmoothnessCostFunction(B, w, w), robust(LossTerm::kPoseSmoothness),
                       {a.bones_t.data(), b.bones_t.data()});
        used_.insert(b.bones_t.data());
      }
    }
  }
  const double joint = losses[LossTerm::kBoneJoint].weight;
  if (B > 1 && joint > 0) {
    // The joints follow the rest bones (re-initialisations, Adam steps).
    const std::vector<BoneJoint> joints = FindBoneJoints(model.bones(), B);
    for (const auto& [v, t] : frames) {
      AddRegularizer(MakeBoneJointCostFunction(B, joints, joint), robust(LossTerm::kBoneJoint),
                     {model.frame(v, t).bones_t.data()});
    }
  }
  used_.insert(model.sdf());
  if (B > 0) used_.insert(model.bones());
}

std::vector<double*> StageProblem::FreeBlocks(const ParameterGroupSet& only) const {
  std::vector<double*> out;
  for (int g = 0; g < kNumParameterGroups; ++g) {
    const ParameterGroup group = static_cast<ParameterGroup>(g);
    if (constant_.Contains(group) || (!only.empty() && !only.Contains(group))) continue;
    for (double* p : groups_[g]) {
      if (used_.count(p)) out.push_back(p);
    }
  }
  return out;
}

void StageProblem::Hold(const ParameterGroupSet& groups) {
  for (int g = 0; g < kNumParameterGroups; ++g) {
    const ParameterGroup group = static_cast<ParameterGroup>(g);
    if (!groups.Contains(group) || constant_.Contains(group)) continue;
    for (double* p : groups_[g]) {
      problem_->SetParameterBlockConstant(p);
      held_.push_back(p);
    }
  }
}

void StageProblem::Restore() {
  for (double* p : held_) problem_->SetParameterBlockVariable(p);
  held_.clear();
  for (int g = 0; g < kNumParameterGroups; ++g) {
    if (!constant_.Contains(static_cast<ParameterGroup>(g))) continue;
    for (double* p : groups_[g]) problem_->SetParameterBlockConstant(p);
  }
}

bool StageProblem::IsMlpWeights(const double* block) const {
  const Model& m = model_;
  return block == m.sdf() || block == m.color() || block == m.embedding() ||
         (m.has_delta_skinning() && block == m.delta_skinning_params());
}

}  // namespace banmo
