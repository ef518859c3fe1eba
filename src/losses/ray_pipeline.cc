// The pipeline of RayBatch::EvaluateRays (losses/ray_batch.h), one method
// per pass over the minibatch's scratch; see ray_pipeline.h.
#include "ray_pipeline.h"

#include <algorithm>
#include <cmath>

#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

void GatherDeltaAdjoints(const std::vector<RayScratch>& scratch, const std::vector<int>& fw_groups,
                         int num_bones, int k, Eigen::MatrixXd* d_bw, Eigen::MatrixXd* d_fw,
                         bool* any) {
  const int B = num_bones;
  int total_samples = 0;
  for (const RayScratch& s : scratch) total_samples += s.num_samples;
  d_bw->setZero(B, total_samples);
  d_fw->setZero(B, fw_groups.back());
  if (any != nullptr) *any = false;
  for (size_t r = 0; r < scratch.size(); ++r) {
    const RayScratch& s = scratch[r];
    if (k >= s.a_dbw.rows()) continue;
    d_bw->middleCols(s.field_offset, s.num_samples) =
        Eigen::Map<const Eigen::MatrixXd>(s.a_dbw.row(k).data(), B, s.num_samples);
    const int count = fw_groups[r + 1] - fw_groups[r];
    d_fw->middleCols(s.fw_offset, count) =
        Eigen::Map<const Eigen::MatrixXd>(s.a_dfw.row(k).data(), B, count);
    if (any != nullptr) {
      *any = *any || s.a_dbw.row(k).squaredNorm() > 0 || s.a_dfw.row(k).squaredNorm() > 0;
    }
  }
}

RayPipeline::RayPipeline(const Model& model, const RayBatchOptions& options,
                         const Eigen::Matrix3Xd& grid, const std::vector<const Ray*>& rays,
                         const std::vector<RayParameters>& params, bool full_jacobians,
                         const RayRobustLosses* robust, std::vector<RayEvaluation>* out,
                         std::vector<double>* ray_cost,
                         std::array<Eigen::VectorXd, 4>* mlp_gradient)
    : model(model),
      field(model.field()),
      options_(options),
      weights(options.weights),
      grid_(grid),
      rays(rays),
      params(params),
      full_jacobians(full_jacobians),
      robust(robust),
      out(out),
      ray_cost(ray_cost),
      mlp_gradient(mlp_gradient),
      gradient(robust != nullptr),
      jacobians(full_jacobians || gradient),
      num_rays(static_cast<int>(rays.size())),
      num_bones(model.num_bones()),
      appearance_dim(model.appearance_size()) {}

void RayPipeline::Run() {
  CHECK_EQ(rays.size(), params.size());
  CHECK(!(gradient && full_jacobians));
  CHECK(!gradient || (ray_cost != nullptr && mlp_gradient != nullptr));
  out->assign(num_rays, RayEvaluation());
  if (gradient) {
    ray_cost->assign(num_rays, 0.0);
    for (auto& g : *mlp_gradient) g.resize(0);
  }
  if (num_rays == 0) return;
  sdf_params = params[0].block[kBlockSdf];
  color_params = params[0].block[kBlockColor];
  embedding_params = params[0].block[kBlockEmbedding];
  delta_params = params[0].block[kBlockDeltaSkin];
  for (const RayParameters& p : params) {
    CHECK(p.block[kBlockSdf] == sdf_params && p.block[kBlockColor] == color_params &&
          p.block[kBlockEmbedding] == embedding_params && p.block[kBlockDeltaSkin] == delta_params)
        << "rays of one EvaluateRays call must share the MLP blocks";
  }
  // Delta skinning (Eq. 14): logits of MLP_Delta added in every warp.
  delta = delta_params != nullptr ? model.delta_skinning() : nullptr;
  pose_code_dim = delta != nullptr ? delta->CodeDim() : 0;
  delta_local_dim = delta != nullptr ? delta->LocalDim() : 0;

  Layout();
  DeltaBackwardInputs();
  PlaceSamples();
  EvaluateFields();
  // Pass 3 (per ray): forward warps, projections, the composite functor with
  // Jets over its locals, the 3D cycle, and the reverse chain to the small
  // parameter blocks.
  ParallelFor(num_rays, [&](int begin, int end) {
    for (int r = begin; r < end; ++r) EvaluateRay(r);
  });
  if (!jacobians) return;
  if (gradient) {
    MlpGradient();
    return;
  }
  if (!field_jacobians) return;
  MlpJacobians();
  DeltaCycle3dJacobians();
}

// The rays' columns in the batched field, embedding and forward-warp passes.
void RayPipeline::Layout() {
  scratch.assign(num_rays, RayScratch());
  field_groups.assign(num_rays + 1, 0);
  match_groups.assign(num_rays + 1, 0);
  emb_groups.assign(num_rays + 1, 0);
  fw_groups.assign(num_rays + 1, 0);
  for (int r = 0; r < num_rays; ++r) {
    const Ray& ray = *rays[r];
    RayScratch& s = scratch[r];
    s.num_samples = ray.NumSamples();
    s.field_offset = field_groups[r];
    field_groups[r + 1] = field_groups[r] + s.num_samples;
    const bool match =
        ray.HasTerm(LossTerm::kFeatureMatch, weights) || ray.HasTerm(LossTerm::kCycle2d, weights);
    if (match) {
      CHECK(!ray.match_indices.empty()) << "feature ray without match indices (call SetRays)";
      CHECK_GT(grid_.cols(), 0);
    }
    s.num_match = match ? static_cast<int>(ray.match_indices.size()) : 0;
    s.match_offset = match_groups[r];
    match_groups[r + 1] = match_groups[r] + s.num_match;
    s.fw_offset = fw_groups[r];
    int fw_count = 0;
    if (delta != nullptr) {
      const bool push_samples =
          ray.HasTerm(LossTerm::kFlow, weights) || ray.HasTerm(LossTerm::kCycle3d, weights);
      s.fw_samples = push_samples ? s.num_samples : 0;
      fw_count = s.fw_samples;
      if (ray.HasTerm(LossTerm::kCycle2d, weights)) s.fw_hat = s.fw_offset + fw_count++;
    }
    fw_groups[r + 1] = fw_groups[r] + fw_count;
  }
  total_samples = field_groups[num_rays];
  total_match = match_groups[num_rays];
  total_fw = fw_groups[num_rays];
}

// Pass 0 (delta skinning only, batched): MLP_Delta at every sample's
// time-t point with the frame's pose code, for the backward warps.
void RayPipeline::DeltaBackwardInputs() {
  if (delta != nullptr) {
    backward_delta.x.resize(3, total_samples);
    backward_delta.codes.resize(pose_code_dim, total_samples);
    ParallelFor(num_rays, [&](int begin, int end) {
      for (int r = begin; r < end; ++r) {
        const Ray& ray = *rays[r];
        const RayParameters& p = params[r];
        const RayScratch& s = scratch[r];
        for (int i = 0; i < s.num_samples; ++i) {
          SampleInRoot(p.block[kBlockRoot], p.root_init, p.block[kBlockIntrinsics], ray.uv.data(),
                       ray.samples.depths[i], backward_delta.x.col(s.field_offset + i).data());
        }
        backward_delta.codes.middleCols(s.field_offset, s.num_samples) =
            Eigen::Map<const Eigen::VectorXd>(p.block[kBlockPoseCode], pose_code_dim)
                .replicate(1, s.num_samples);
      }
    });
    delta->ForwardBatch(delta_params, &backward_delta, jacobians);
  }
}

const double* RayPipeline::bw_logits(int col) const {
  return delta != nullptr ? backward_delta.logits.col(col).data() : nullptr;
}
const double* RayPipeline::fw_logits(int col) const {
  return delta != nullptr ? forward_delta.logits.col(col).data() : nullptr;
}

// Pass 1 (per ray): sample placement, view direction, backward warp.
void RayPipeline::PlaceSamples() {
  field_batch.x.resize(3, total_samples);
  field_batch.view_dir.resize(3, total_samples);
  field_batch.appearance.resize(appearance_dim, total_samples);

  ParallelFor(num_rays, [&](int begin, int end) {
    for (int r = begin; r < end; ++r) {
      const Ray& ray = *rays[r];
      const RayParameters& p = params[r];
      RayScratch& s = scratch[r];
      const int n = s.num_samples;
      const double* root = p.block[kBlockRoot];
      const double* intr = p.block[kBlockIntrinsics];
      s.x_root.resize(3, n);
      s.x_star.resize(3, n);
      if (jacobians) {
        s.dxroot_droot.resize(n);
        s.dxroot_dk.resize(n);
        s.backward.resize(n);
      }
      for (int i = 0; i < n; ++i) {
        const double depth = ray.samples.depths[i];
        if (jacobians) {
          using J = JetN<kPoseIntrinsics>;
          J pose[kPoseSize], k[kIntrinsicsSize], x[3];
          SeedJets(root, kPoseSize, 0, pose);
          SeedJets(intr, kIntrinsicsSize, kPoseSize, k);
          SampleInRoot(pose, p.root_init, k, ray.uv.data(), depth, x);
          for (int c = 0; c < 3; ++c) {
            s.x_root(c, i) = x[c].a;
            s.dxroot_droot[i].row(c) = x[c].v.head<kPoseSize>().transpose();
            s.dxroot_dk[i].row(c) = x[c].v.tail<kIntrinsicsSize>().transpose();
          }
          WarpWithJacobian(WarpDirection::kBackward, num_bones, p.block[kBlockBones],
                           p.block[kBlockBonesT], s.x_root.col(i).data(), s.x_star.col(i).data(),
                           &s.backward[i], bw_logits(s.field_offset + i),
                           options_.skinning_jacobian_cutoff);
        } else {
          SampleInRoot(root, p.root_init, intr, ray.uv.data(), depth, s.x_root.col(i).data());
          BackwardWarp(num_bones, p.block[kBlockBones], p.block[kBlockBonesT],
                       s.x_root.col(i).data(), s.x_star.col(i).data(),
                       bw_logits(s.field_offset + i));
        }
      }
      if (jacobians) {
        using J = JetN<kPoseIntrinsics>;
        J pose[kPoseSize], k[kIntrinsicsSize], v[3];
        SeedJets(root, kPoseSize, 0, pose);
        SeedJets(intr, kIntrinsicsSize, kPoseSize, k);
        ViewDirectionInRoot(pose, p.root_init, k, ray.uv.data(), v);
        for (int c = 0; c < 3; ++c) {
          s.view[c] = v[c].a;
          s.dview_droot.row(c) = v[c].v.head<kPoseSize>().transpose();
          s.dview_dk.row(c) = v[c].v.tail<kIntrinsicsSize>().transpose();
        }
      } else {
        ViewDirectionInRoot(root, p.root_init, intr, ray.uv.data(), s.view.data());
      }
      field_batch.x.middleCols(s.field_offset, n) = s.x_star;
      field_batch.view_dir.middleCols(s.field_offset, n) = s.view.replicate(1, n);
      if (appearance_dim > 0) {
        const Eigen::Map<const Eigen::VectorXd> code(p.block[kBlockAppearance], appearance_dim);
        field_batch.appearance.middleCols(s.field_offset, n) = code.replicate(1, n);
      }
    }
  });
}

// Pass 2 (batched): canonical fields at all samples; embeddings at the
// samples of rays with the rendered embedding, at the rays' match
// candidates and the soft-argmax X_hat* (Eq. 15); MLP_Delta at the points
// the forward warps push.
void RayPipeline::EvaluateFields() {
  // The colour MLP runs only where a ray reads a colour: at the samples of
  // rays with the rgb term (Ray::HasTerm) whose rendering weight reaches
  // kMinWarpTau (RayCompositeFunctor reads no other), so the weights come
  // first, from the SDF values.
  const bool any_color = weights[LossTerm::kRgb] > 0.0;
  if (!jacobians && !any_color) {
    // Nothing is differentiated and no colour read (the importance pass's
    // coarse evaluation, silhouette only): no colour MLP state at all.
    field.ForwardSdfBatch(sdf_params, &field_batch, false);
  } else {
    field.ForwardGeometryBatch(sdf_params, &field_batch, jacobians);
  }
  ParallelFor(num_rays, [&](int begin, int end) {
    for (int r = begin; r < end; ++r) {
      const RayScratch& s = scratch[r];
      RayEvaluation& ev = (*out)[r];
      ev.sdf.assign(field_batch.sdf.data() + s.field_offset,
                    field_batch.sdf.data() + s.field_offset + s.num_samples);
      ev.tau.resize(s.num_samples);
      CompositeWeights(s.num_samples, ev.sdf.data(), *params[r].block[kBlockLogBeta],
                       rays[r]->samples.deltas.data(), model.options().density, ev.tau.data());
    }
  });
  // The samples that count (tau_i >= kMinWarpTau) of the rays with the rgb
  // term are the colour MLP's columns, and those of the rays with the
  // rendered embedding its samples (RayCompositeFunctor reads no other).
  std::vector<int> columns;
  for (int r = 0; r < num_rays; ++r) {
    RayScratch& s = scratch[r];
    s.emb_samples.clear();
    const bool rgb = any_color && rays[r]->HasTerm(LossTerm::kRgb, weights);
    const bool emb = rays[r]->HasTerm(LossTerm::kFeatureRender, weights);
    const std::vector<double>& tau = (*out)[r].tau;
    for (int i = 0; i < s.num_samples && (rgb || emb); ++i) {
      if (!WarpsSample(tau[i])) continue;
      if (rgb) columns.push_back(s.field_offset + i);
      if (emb) s.emb_samples.push_back(i);
    }
    s.num_emb = static_cast<int>(s.emb_samples.size());
    s.emb_offset = emb_groups[r];
    emb_groups[r + 1] = emb_groups[r] + s.num_emb;
  }
  total_emb = emb_groups[num_rays];
  if (jacobians || any_color)
    field.ForwardColorBatch(color_params, columns, &field_batch, jacobians);
  if (total_emb > 0) {
    sample_batch.x.resize(3, total_emb);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      for (int j = 0; j < s.num_emb; ++j)
        sample_batch.x.col(s.emb_offset + j) = s.x_star.col(s.emb_samples[j]);
    }
    // d psi / d X*_i only when the term moves the samples (not embedding-only).
    field.ForwardEmbeddingBatch(embedding_params, &sample_batch,
                                jacobians && !options_.feature_render_embedding_only);
  }
  if (total_match > 0) {
    match_batch.x.resize(3, total_match);
    for (int r = 0; r < num_rays; ++r) {
      const Ray& ray = *rays[r];
      for (int k = 0; k < scratch[r].num_match; ++k) {
        match_batch.x.col(scratch[r].match_offset + k) = grid_.col(ray.match_indices[k]);
      }
    }
    field.ForwardEmbeddingBatch(embedding_params, &match_batch, false);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      if (s.num_match == 0) continue;
      const Eigen::MatrixXd psi = match_batch.psi.middleCols(s.match_offset, s.num_match);
      const Eigen::Matrix3Xd points = match_batch.x.middleCols(s.match_offset, s.num_match);
      SoftArgmax(rays[r]->feature.data(), psi.data(), points.data(), s.num_match,
                 options_.matcher.temperature, scratch[r].x_hat.data());
    }
  }
  // Delta skinning, forward warps: MLP_Delta at the canonical points pushed
  // forward (X*_i, X_hat*) with the rest-pose code.
  if (delta != nullptr && total_fw > 0) {
    forward_delta.x.resize(3, total_fw);
    forward_delta.codes.resize(pose_code_dim, total_fw);
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      const Eigen::Map<const Eigen::VectorXd> rest_code(params[r].block[kBlockRestPoseCode],
                                                        pose_code_dim);
      forward_delta.x.middleCols(s.fw_offset, s.fw_samples) = s.x_star.leftCols(s.fw_samples);
      if (s.fw_hat >= 0) forward_delta.x.col(s.fw_hat) = s.x_hat;
      const int count = fw_groups[r + 1] - fw_groups[r];
      forward_delta.codes.middleCols(s.fw_offset, count) = rest_code.replicate(1, count);
    }
    delta->ForwardBatch(delta_params, &forward_delta, jacobians);
  }
}

RayPipeline::RayWork::RayWork(int r, const Ray& ray, const RayParameters& p, RayScratch& s,
                              RayEvaluation& ev, const RayLossWeights& weights,
                              DensityModel density)
    : ray_index(r),
      ray(ray),
      params(p),
      scratch(s),
      eval(ev),
      num_samples(s.num_samples),
      bones(p.block[kBlockBones]),
      intr(p.block[kBlockIntrinsics]),
      composite(ray, weights, density),
      rows(composite.num_residuals()),
      cycle3d(ray.HasTerm(LossTerm::kCycle3d, weights)) {}

void RayPipeline::EvaluateRay(int r) {
  RayWork w(r, *rays[r], params[r], scratch[r], (*out)[r], weights, model.options().density);
  // Rows of the reverse chain: all rows, or one cotangent row in gradient mode.
  w.chain_rows = gradient ? std::min(w.rows, 1) : w.rows;
  w.scratch.composite_rows = w.chain_rows;
  InitEvaluation(w);
  CompositeInputs(w);
  CompositeResiduals(w);
  if (!RenderingWeights(w)) return;
  ReverseComposite(w);
  Cycle3dGradient(w);
  Cycle3dRows(w);
}

// The ray's residual rows (composite terms in table order, then the 3D cycle)
// and Jacobian blocks.
void RayPipeline::InitEvaluation(RayWork& w) {
  RayEvaluation& ev = w.eval;
  const int n = w.num_samples;
  const int R = w.rows;
  const int Rc = w.chain_rows;
  const bool cycle3d = w.cycle3d;
  const int total_rows = R + (cycle3d ? 3 * n : 0);
  ev.residuals.assign(total_rows, 0.0);
  ev.term_row.fill(-1);
  {
    int row = 0;
    for (int t = 0; t < kNumCompositeTerms; ++t) {
      if (w.composite.active(RayTerm(t))) {
        ev.term_row[t] = row;
        row += LossTermResiduals(RayTerm(t), n);
      }
    }
    if (cycle3d) ev.term_row[static_cast<int>(LossTerm::kCycle3d)] = R;
  }
  const std::array<int, kNumRayBlocks> sizes = RayBlockSizes(model, w.params);
  if (jacobians) {
    ev.has_jacobians = !gradient;
    for (int b = 0; b < kNumRayBlocks; ++b) {
      const bool mlp = b == kBlockSdf || b == kBlockColor || b == kBlockEmbedding;
      const bool skipped = !field_jacobians && (mlp || b == kBlockDeltaSkin);
      ev.jacobians[b].setZero(mlp ? Rc : (gradient ? 1 : total_rows), skipped ? 0 : sizes[b]);
    }
  }
}

void RayPipeline::CompositeInputs(RayWork& w) {
  const Ray& ray = w.ray;
  const RayParameters& p = w.params;
  RayScratch& s = w.scratch;
  const int n = w.num_samples;
  const double* bones = w.bones;
  const double* intr = w.intr;
  const CompositeLocals& L = w.composite.locals();
  std::vector<double>& u = w.locals;
  std::vector<WarpJacobian>& flow_warp = w.flow_warp;
  std::vector<ProjectionJacobian>& flow_proj = w.flow_proj;
  WarpJacobian& cycle_warp = w.cycle_warp;
  ProjectionJacobian& cycle_proj = w.cycle_proj;
  // Locals of the composite functor.
  u.assign(L.size, 0.0);
  for (int i = 0; i < n; ++i) {
    const int col = s.field_offset + i;
    u[L.sdf + i] = field_batch.sdf(col);
    if (L.has_rgb) {
      for (int c = 0; c < 3; ++c) u[L.rgb + 3 * i + c] = field_batch.rgb(c, col);
    }
    if (L.has_matched) {
      for (int c = 0; c < 3; ++c) u[L.canonical + 3 * i + c] = s.x_star(c, i);
    }
  }
  u[L.log_beta] = *p.block[kBlockLogBeta];
  // Rendering weights: EvaluateFields computed them (ev.sdf, ev.tau).
  RayEvaluation& ev = w.eval;
  // Flow: each X*_i pushed with the forward warp of t' and projected (Eq. 6),
  // the samples the flow sums only (weight >= kMinWarpTau; the others'
  // displacements stay 0, unread).
  flow_warp.resize(L.has_displacement && jacobians ? n : 0);
  flow_proj.resize(flow_warp.size());
  w.flow_active.assign(L.has_displacement ? n : 0, 0);
  if (L.has_displacement) {
    for (int i = 0; i < n; ++i) {
      w.flow_active[i] = WarpsSample(ev.tau[i]);
      if (!w.flow_active[i]) continue;
      Eigen::Vector3d x_t2;
      Eigen::Vector2d uv2;
      if (jacobians) {
        WarpWithJacobian(WarpDirection::kForward, num_bones, bones, p.block[kBlockPartnerBonesT],
                         s.x_star.col(i).data(), x_t2.data(), &flow_warp[i],
                         fw_logits(s.fw_offset + i), options_.skinning_jacobian_cutoff);
        ProjectWithJacobian(p.block[kBlockPartnerRoot], p.partner_root_init, intr, x_t2.data(),
                            uv2.data(), &flow_proj[i]);
      } else {
        ForwardWarp(num_bones, bones, p.block[kBlockPartnerBonesT], s.x_star.col(i).data(),
                    x_t2.data(), fw_logits(s.fw_offset + i));
        ProjectRootPoint(p.block[kBlockPartnerRoot], p.partner_root_init, intr, x_t2.data(),
                         uv2.data());
      }
      u[L.displacement + 2 * i + 0] = uv2[0] - ray.uv[0];
      u[L.displacement + 2 * i + 1] = uv2[1] - ray.uv[1];
    }
  }
  if (L.has_matched) {
    for (int c = 0; c < 3; ++c) u[L.matched + c] = s.x_hat[c];
  }
  if (L.has_embedding) {
    constexpr int E = CompositeLocals::kEmbeddingDim;
    // The samples left out (weight under kMinWarpTau) are not read.
    std::fill(u.begin() + L.embedding, u.begin() + L.embedding + E * n, 0.0);
    for (int j = 0; j < s.num_emb; ++j) {
      const int i = s.emb_samples[j];
      for (int c = 0; c < E; ++c)
        u[L.embedding + E * i + c] = sample_batch.psi(c, s.emb_offset + j);
    }
  }
  // 2D cycle: X_hat* pushed forward to t and projected (Eq. 18).
  if (L.has_cycle) {
    Eigen::Vector3d x_t;
    Eigen::Vector2d uv_c;
    if (jacobians) {
      WarpWithJacobian(WarpDirection::kForward, num_bones, bones, p.block[kBlockBonesT],
                       s.x_hat.data(), x_t.data(), &cycle_warp, fw_logits(s.fw_hat),
                       options_.skinning_jacobian_cutoff);
      ProjectWithJacobian(p.block[kBlockRoot], p.root_init, intr, x_t.data(), uv_c.data(),
                          &cycle_proj);
    } else {
      ForwardWarp(num_bones, bones, p.block[kBlockBonesT], s.x_hat.data(), x_t.data(),
                  fw_logits(s.fw_hat));
      ProjectRootPoint(p.block[kBlockRoot], p.root_init, intr, x_t.data(), uv_c.data());
    }
    u[L.cycle_projection + 0] = uv_c[0];
    u[L.cycle_projection + 1] = uv_c[1];
  }
}

void RayPipeline::CompositeResiduals(RayWork& w) {
  RayEvaluation& ev = w.eval;
  const int r = w.ray_index;
  const int n = w.num_samples;
  const RayCompositeFunctor& composite = w.composite;
  const int R = w.rows;
  std::vector<double>& u = w.locals;
  RowMajorMatrix& D = w.locals_jacobian;
  const int render_row = ev.term_row[static_cast<int>(LossTerm::kFeatureRender)];
  if (R > 0) {
    if (jacobians) {
      // The embedding inputs (last in the locals) in closed form: 16 N fewer Jet
      // directions. Embedding-only, the term's other columns are not wanted
      // either, and it leaves the Jets altogether.
      const CompositeLocals& L = composite.locals();
      const bool skip = L.has_embedding && options_.feature_render_embedding_only;
      ChunkedJacobian<32>(
          [&](const auto* x, auto* out) { return composite.Evaluate(x, out, skip); }, u, R,
          ev.residuals.data(), &D, L.has_embedding ? L.embedding : -1);
      if (L.has_embedding) {
        constexpr int E = CompositeLocals::kEmbeddingDim;
        composite.EmbeddingJacobian(u.data(), D.block(render_row, L.embedding, E, E * n),
                                    skip ? ev.residuals.data() + render_row : nullptr);
      }
    } else {
      composite(u.data(), ev.residuals.data());
    }
  }
  // Embedding-only: only d r / d psi_i; the rendering weights (from the SDF
  // values and log beta) are held at their values (the rows' other columns
  // stay zero: ChunkedJacobian above), the psi_i's inputs X*_i in the
  // reverse chain (ReverseComposite).
  if (gradient && R > 0) {
    // Each composite term's rows collapse into c = rho'(s) r, s = |r_term|^2.
    Eigen::RowVectorXd c(R);
    for (int t = 0; t < kNumCompositeTerms; ++t) {
      const int row = ev.term_row[t];
      if (row < 0) continue;
      const int rows = LossTermResiduals(RayTerm(t), n);
      const Eigen::Map<const Eigen::RowVectorXd> r_t(ev.residuals.data() + row, rows);
      const double sq = r_t.squaredNorm();
      double rho[3] = {sq, 1.0, 0.0};
      if ((*robust)[t] != nullptr) (*robust)[t]->Evaluate(sq, rho);
      (*ray_cost)[r] += 0.5 * rho[0];
      c.segment(row, rows) = rho[1] * r_t;
    }
    D = (c * D).eval();
  }
}

bool RayPipeline::RenderingWeights(RayWork& w) {
  const Ray& ray = w.ray;
  const RayParameters& p = w.params;
  RayScratch& s = w.scratch;
  RayEvaluation& ev = w.eval;
  const int n = w.num_samples;
  const double* bones = w.bones;
  const double* intr = w.intr;
  const int R = w.rows;
  const bool cycle3d = w.cycle3d;
  // The 3D cycle (Eq. 19) uses the ray's fixed cycle_tau when set (the
  // minibatch's constants), else the rendering weights of CompositeInputs.
  w.tau = ray.cycle_tau.empty() ? &ev.tau : &ray.cycle_tau;
  const std::vector<double>& tau = *w.tau;
  CHECK_EQ(static_cast<int>(tau.size()), n);

  if (!jacobians) {
    if (cycle3d) {
      for (int i = 0; i < n; ++i) {
        const Cycle3dLoss loss(tau[i], weights[LossTerm::kCycle3d]);
        if (!loss.active()) continue;  // rows stay 0
        Eigen::Vector3d q;
        ForwardWarp(num_bones, bones, p.block[kBlockBonesT], s.x_star.col(i).data(), q.data(),
                    fw_logits(s.fw_offset + i));
        Cycle3dResidual(loss, p.block[kBlockRoot], p.root_init, intr, ray.uv.data(),
                        ray.samples.depths[i], q.data(), ev.residuals.data() + R + 3 * i);
      }
    }
    return false;
  }
  return true;
}

// Chains adjoints a (rows x 3) of a warp's output through its delta
// logits: a_dl = a dOut/dlogits (rows x B) goes to the batch column's
// adjoint (*a_logits, rows x B), to the warp input's adjoint (*a_in,
// rows x 3) and to the pose-code block's Jacobian rows.
void RayPipeline::ChainDelta(RayJacobians& jac, const Eigen::Ref<const RowMajorMatrix>& a,
                             const WarpJacobian& wj, const DeltaSkinningBatch& batch, int col,
                             RayBlock code_block, int row0, Eigen::Ref<RowMajorMatrix> a_logits,
                             Eigen::Ref<RowMajorMatrix> a_in) const {
  const RowMajorMatrix a_dl = a * wj.d_delta_logits;
  const auto jd =
      batch.jacobian.middleCols(static_cast<Eigen::Index>(delta_local_dim) * col, delta_local_dim);
  a_in.noalias() += a_dl * jd.leftCols<3>();
  AddProduct(&jac[code_block], row0, a_dl, jd.rightCols(pose_code_dim));
  a_logits += a_dl;
}

void RayPipeline::ReverseComposite(RayWork& w) {
  RayScratch& s = w.scratch;
  const int r = w.ray_index;
  const int n = w.num_samples;
  const CompositeLocals& L = w.composite.locals();
  const int Rc = w.chain_rows;
  const bool cycle3d = w.cycle3d;
  std::vector<WarpJacobian>& flow_warp = w.flow_warp;
  std::vector<ProjectionJacobian>& flow_proj = w.flow_proj;
  WarpJacobian& cycle_warp = w.cycle_warp;
  ProjectionJacobian& cycle_proj = w.cycle_proj;
  RowMajorMatrix& D = w.locals_jacobian;
  auto& jac = w.eval.jacobians;
  // ---- Reverse chain (composite rows). ----
  RowMajorMatrix a_xstar = RowMajorMatrix::Zero(Rc, 3 * n);
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> a_view =
      Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>::Zero(Rc, 3);
  s.a_sdf = RowMajorMatrix::Zero(Rc, n);
  s.a_rgb = RowMajorMatrix::Zero(Rc, 3 * n);
  s.a_xhat = RowMajorMatrix::Zero(Rc, 3);
  s.a_psi = RowMajorMatrix::Zero(Rc, s.num_emb * CompositeLocals::kEmbeddingDim);
  if (delta != nullptr) {
    // Gradient mode: one cotangent row shared by the composite and 3D-cycle terms.
    const int rows = gradient ? 1 : Rc;
    s.a_dbw = RowMajorMatrix::Zero(rows, num_bones * n);
    s.a_dfw = RowMajorMatrix::Zero(rows, num_bones * (fw_groups[r + 1] - fw_groups[r]));
    if (cycle3d && !gradient) {
      s.c3_dbw = RowMajorMatrix::Zero(3 * n, num_bones);
      s.c3_dfw = RowMajorMatrix::Zero(3 * n, num_bones);
    }
  }
  if (Rc > 0) {
    s.a_sdf = D.middleCols(L.sdf, n);
    if (L.has_rgb) s.a_rgb = D.middleCols(L.rgb, 3 * n);
    if (L.has_matched) {
      a_xstar += D.middleCols(L.canonical, 3 * n);
      s.a_xhat += D.middleCols(L.matched, 3);
    }
    if (L.has_embedding) {
      constexpr int E = CompositeLocals::kEmbeddingDim;
      for (int j = 0; j < s.num_emb; ++j) {
        s.a_psi.middleCols<E>(E * j) = D.middleCols<E>(L.embedding + E * s.emb_samples[j]);
      }
    }
    jac[kBlockLogBeta].topRows(Rc).col(0) += D.col(L.log_beta);
  }
  // Field inputs: X*_i, view direction, appearance code.
  for (int i = 0; i < n && Rc > 0; ++i) {
    const int col = s.field_offset + i;
    a_xstar.middleCols<3>(3 * i).noalias() +=
        s.a_sdf.col(i) * field_batch.dsdf_dx.col(col).transpose();
    if (L.has_rgb) {
      const auto a_rgb_i = s.a_rgb.middleCols<3>(3 * i);
      a_xstar.middleCols<3>(3 * i).noalias() +=
          a_rgb_i * field_batch.drgb_dx.middleCols<3>(3 * col);
      if (field.options().use_view_direction) {
        a_view.noalias() += a_rgb_i * field_batch.drgb_dview.middleCols<3>(3 * col);
      }
      if (appearance_dim > 0) {
        AddProduct(&jac[kBlockAppearance], 0, a_rgb_i,
                   field_batch.drgb_dappearance.middleCols(appearance_dim * col, appearance_dim));
      }
    }
  }
  // The rendered embedding's samples (unless embedding-only: then the
  // term does not move them).
  if (Rc > 0 && L.has_embedding && !options_.feature_render_embedding_only) {
    constexpr int E = CompositeLocals::kEmbeddingDim;
    for (int j = 0; j < s.num_emb; ++j) {
      a_xstar.middleCols<3>(3 * s.emb_samples[j]).noalias() +=
          s.a_psi.middleCols<E>(E * j) * sample_batch.dpsi_dx.middleCols<3>(3 * (s.emb_offset + j));
    }
  }
  // Flow: displacement_i = Pi_{t'}(G^{t'} W^{t',->}(X*_i)) - x.
  if (L.has_displacement) {
    for (int i = 0; i < n; ++i) {
      if (!w.flow_active[i]) continue;  // not read by the flow
      const auto a_disp = D.middleCols<2>(L.displacement + 2 * i);
      const Eigen::Matrix<double, Eigen::Dynamic, 3> a_p = a_disp * flow_proj[i].leftCols<3>();
      AddProduct(&jac[kBlockPartnerRoot], 0, a_disp, flow_proj[i].middleCols<kPoseSize>(3));
      AddProduct(&jac[kBlockIntrinsics], 0, a_disp, flow_proj[i].rightCols<kIntrinsicsSize>());
      a_xstar.middleCols<3>(3 * i).noalias() += a_p * flow_warp[i].d_x;
      AddProduct(&jac[kBlockBones], 0, a_p, flow_warp[i].d_bones);
      AddProduct(&jac[kBlockPartnerBonesT], 0, a_p, flow_warp[i].d_bones_t);
      if (delta != nullptr) {
        ChainDelta(jac, a_p, flow_warp[i], forward_delta, s.fw_offset + i, kBlockRestPoseCode, 0,
                   s.a_dfw.block(0, num_bones * i, a_p.rows(), num_bones),
                   a_xstar.middleCols<3>(3 * i));
      }
    }
  }
  // 2D cycle: Pi_t(G^t W^{t,->}(X_hat*)).
  if (L.has_cycle) {
    const auto a_c = D.middleCols<2>(L.cycle_projection);
    const Eigen::Matrix<double, Eigen::Dynamic, 3> a_p = a_c * cycle_proj.leftCols<3>();
    AddProduct(&jac[kBlockRoot], 0, a_c, cycle_proj.middleCols<kPoseSize>(3));
    AddProduct(&jac[kBlockIntrinsics], 0, a_c, cycle_proj.rightCols<kIntrinsicsSize>());
    s.a_xhat.noalias() += a_p * cycle_warp.d_x;
    AddProduct(&jac[kBlockBones], 0, a_p, cycle_warp.d_bones);
    AddProduct(&jac[kBlockBonesT], 0, a_p, cycle_warp.d_bones_t);
    if (delta != nullptr) {
      ChainDelta(jac, a_p, cycle_warp, forward_delta, s.fw_hat, kBlockRestPoseCode, 0,
                 s.a_dfw.block(0, num_bones * (s.fw_hat - s.fw_offset), a_p.rows(), num_bones),
                 s.a_xhat);
    }
  }
  // Backward warp and sample placement of every X*_i.
  for (int i = 0; i < n && Rc > 0; ++i) {
    const auto a_x = a_xstar.middleCols<3>(3 * i);
    RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
    if (delta != nullptr) {
      ChainDelta(jac, a_x, s.backward[i], backward_delta, s.field_offset + i, kBlockPoseCode, 0,
                 s.a_dbw.block(0, num_bones * i, Rc, num_bones), a_root_pt);
    }
    AddProduct(&jac[kBlockBones], 0, a_x, s.backward[i].d_bones);
    AddProduct(&jac[kBlockBonesT], 0, a_x, s.backward[i].d_bones_t);
    AddProduct(&jac[kBlockRoot], 0, a_root_pt, s.dxroot_droot[i]);
    AddProduct(&jac[kBlockIntrinsics], 0, a_root_pt, s.dxroot_dk[i]);
  }
  if (Rc > 0) {
    AddProduct(&jac[kBlockRoot], 0, a_view, s.dview_droot);
    AddProduct(&jac[kBlockIntrinsics], 0, a_view, s.dview_dk);
  }
}

// Sample i's 3D-cycle residual (Eq. 19) into the ray's rows, the forward
// warp's Jacobian *qj, and the residual's Jacobian *E wrt [q (the
// forward-warped point), root_delta, intrinsics].
void RayPipeline::Cycle3dSample(RayWork& w, int i, WarpJacobian* qj, Cycle3dJacobian* E) const {
  const RayParameters& p = w.params;
  const RayScratch& s = w.scratch;
  using J = JetN<kPointPoseIntrinsics>;
  Eigen::Vector3d q;
  WarpWithJacobian(WarpDirection::kForward, num_bones, w.bones, p.block[kBlockBonesT],
                   s.x_star.col(i).data(), q.data(), qj, fw_logits(s.fw_offset + i),
                   options_.skinning_jacobian_cutoff);
  J qj_jet[3], pose[kPoseSize], k[kIntrinsicsSize], res[3];
  SeedJets(q.data(), 3, 0, qj_jet);
  SeedJets(p.block[kBlockRoot], kPoseSize, 3, pose);
  SeedJets(w.intr, kIntrinsicsSize, 3 + kPoseSize, k);
  Cycle3dResidual(Cycle3dLoss((*w.tau)[i], weights[LossTerm::kCycle3d]), pose, p.root_init, k,
                  w.ray.uv.data(), w.ray.samples.depths[i], qj_jet, res);
  for (int c = 0; c < 3; ++c) {
    w.eval.residuals[w.rows + 3 * i + c] = res[c].a;
    E->row(c) = res[c].v.transpose();
  }
}

void RayPipeline::Cycle3dGradient(RayWork& w) {
  RayScratch& s = w.scratch;
  RayEvaluation& ev = w.eval;
  const int r = w.ray_index;
  const int n = w.num_samples;
  const int R = w.rows;
  const bool cycle3d = w.cycle3d;
  auto& jac = w.eval.jacobians;
  // ---- 3D cycle, gradient mode: all residuals first (rho' needs the
  // whole term's |r|^2), then one cotangent row c_i^T E_i per sample. ----
  if (cycle3d && gradient) {
    // Samples of weight below kMinWarpTau: residual 0, skipped.
    std::vector<char> active(n);
    std::vector<WarpJacobian> qjs(n);
    std::vector<Cycle3dJacobian> Es(n);
    for (int i = 0; i < n; ++i) {
      active[i] = Cycle3dLoss((*w.tau)[i], weights[LossTerm::kCycle3d]).active();
      if (active[i]) Cycle3dSample(w, i, &qjs[i], &Es[i]);
    }
    const Eigen::Map<const Eigen::VectorXd> r_t(ev.residuals.data() + R, 3 * n);
    const double sq = r_t.squaredNorm();
    double rho[3] = {sq, 1.0, 0.0};
    const int t = static_cast<int>(LossTerm::kCycle3d);
    if ((*robust)[t] != nullptr) (*robust)[t]->Evaluate(sq, rho);
    (*ray_cost)[r] += 0.5 * rho[0];
    for (int i = 0; i < n; ++i) {
      if (!active[i]) continue;
      const Eigen::Matrix<double, 1, kPointPoseIntrinsics> e =
          rho[1] * r_t.segment<3>(3 * i).transpose() * Es[i];
      const Eigen::Matrix<double, 1, 3> a_q = e.leftCols<3>();
      AddProduct(&jac[kBlockRoot], 0, e.middleCols<kPoseSize>(3),
                 Eigen::Matrix<double, kPoseSize, kPoseSize>::Identity());
      AddProduct(&jac[kBlockIntrinsics], 0, e.rightCols<kIntrinsicsSize>(),
                 Eigen::Matrix<double, kIntrinsicsSize, kIntrinsicsSize>::Identity());
      RowMajorMatrix a_x = a_q * qjs[i].d_x;
      AddProduct(&jac[kBlockBones], 0, a_q, qjs[i].d_bones);
      AddProduct(&jac[kBlockBonesT], 0, a_q, qjs[i].d_bones_t);
      if (delta != nullptr) {
        ChainDelta(jac, a_q, qjs[i], forward_delta, s.fw_offset + i, kBlockRestPoseCode, 0,
                   s.a_dfw.block(0, num_bones * i, 1, num_bones), a_x);
      }
      RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
      if (delta != nullptr) {
        ChainDelta(jac, a_x, s.backward[i], backward_delta, s.field_offset + i, kBlockPoseCode, 0,
                   s.a_dbw.block(0, num_bones * i, 1, num_bones), a_root_pt);
      }
      AddProduct(&jac[kBlockBones], 0, a_x, s.backward[i].d_bones);
      AddProduct(&jac[kBlockBonesT], 0, a_x, s.backward[i].d_bones_t);
      AddProduct(&jac[kBlockRoot], 0, a_root_pt, s.dxroot_droot[i]);
      AddProduct(&jac[kBlockIntrinsics], 0, a_root_pt, s.dxroot_dk[i]);
    }
  }
}

void RayPipeline::Cycle3dRows(RayWork& w) {
  RayScratch& s = w.scratch;
  const int n = w.num_samples;
  const int R = w.rows;
  const bool cycle3d = w.cycle3d;
  auto& jac = w.eval.jacobians;
  // ---- 3D cycle rows: 3 per sample, small blocks only. ----
  if (cycle3d && !gradient) {
    for (int i = 0; i < n; ++i) {
      // Weight below kMinWarpTau: rows and Jacobian stay 0.
      if (!Cycle3dLoss((*w.tau)[i], weights[LossTerm::kCycle3d]).active()) continue;
      const int row0 = R + 3 * i;
      WarpJacobian qj;
      Cycle3dJacobian E;
      Cycle3dSample(w, i, &qj, &E);
      const Eigen::Matrix3d a_q = E.leftCols<3>();
      AddProduct(&jac[kBlockRoot], row0, E.middleCols<kPoseSize>(3),
                 Eigen::Matrix<double, kPoseSize, kPoseSize>::Identity());
      AddProduct(&jac[kBlockIntrinsics], row0, E.rightCols<kIntrinsicsSize>(),
                 Eigen::Matrix<double, kIntrinsicsSize, kIntrinsicsSize>::Identity());
      RowMajorMatrix a_x = a_q * qj.d_x;
      AddProduct(&jac[kBlockBones], row0, a_q, qj.d_bones);
      AddProduct(&jac[kBlockBonesT], row0, a_q, qj.d_bones_t);
      if (delta != nullptr) {
        ChainDelta(jac, a_q, qj, forward_delta, s.fw_offset + i, kBlockRestPoseCode, row0,
                   s.c3_dfw.middleRows(3 * i, 3), a_x);
      }
      RowMajorMatrix a_root_pt = a_x * s.backward[i].d_x;
      if (delta != nullptr) {
        ChainDelta(jac, a_x, s.backward[i], backward_delta, s.field_offset + i, kBlockPoseCode,
                   row0, s.c3_dbw.middleRows(3 * i, 3), a_root_pt);
      }
      AddProduct(&jac[kBlockBones], row0, a_x, s.backward[i].d_bones);
      AddProduct(&jac[kBlockBonesT], row0, a_x, s.backward[i].d_bones_t);
      AddProduct(&jac[kBlockRoot], row0, a_root_pt, s.dxroot_droot[i]);
      AddProduct(&jac[kBlockIntrinsics], row0, a_root_pt, s.dxroot_dk[i]);
    }
  }
}

void RayPipeline::MatchPsiCotangent(int k, Eigen::MatrixXd* d_psi) const {
  d_psi->setZero(kEmbeddingFeatureDim, total_match);
  for (int r = 0; r < num_rays; ++r) {
    const RayScratch& s = scratch[r];
    if (k >= s.composite_rows || s.num_match == 0) continue;
    const Eigen::MatrixXd psi = match_batch.psi.middleCols(s.match_offset, s.num_match);
    const Eigen::Matrix3Xd points = match_batch.x.middleCols(s.match_offset, s.num_match);
    const Eigen::Vector3d a = s.a_xhat.row(k).transpose();
    Eigen::MatrixXd dpsi;
    SoftArgmaxBackward(rays[r]->feature.data(), psi.data(), points.data(), s.num_match,
                       options_.matcher.temperature, a.data(), &dpsi, nullptr);
    d_psi->middleCols(s.match_offset, s.num_match) = dpsi;
  }
}

void RayPipeline::SamplePsiCotangent(int k, Eigen::MatrixXd* d_psi) const {
  d_psi->setZero(kEmbeddingFeatureDim, total_emb);
  for (int r = 0; r < num_rays; ++r) {
    const RayScratch& s = scratch[r];
    if (k >= s.composite_rows || s.num_emb == 0) continue;
    d_psi->middleCols(s.emb_offset, s.num_emb) =
        Eigen::Map<const Eigen::MatrixXd>(s.a_psi.row(k).data(), kEmbeddingFeatureDim, s.num_emb);
  }
}

// Pass 4, gradient mode: ONE backward pass per MLP over the whole
// minibatch (a single group) with the rays' cotangent rows.
void RayPipeline::MlpGradient() {
  Eigen::VectorXd d_sdf = Eigen::VectorXd::Zero(total_samples);
  Eigen::Matrix3Xd d_rgb = Eigen::Matrix3Xd::Zero(3, total_samples);
  for (int r = 0; r < num_rays; ++r) {
    const RayScratch& s = scratch[r];
    if (s.composite_rows == 0) continue;
    for (int i = 0; i < s.num_samples; ++i) {
      d_sdf(s.field_offset + i) = s.a_sdf(0, i);
      for (int c = 0; c < 3; ++c) d_rgb(c, s.field_offset + i) = s.a_rgb(0, 3 * i + c);
    }
  }
  Eigen::MatrixXd d_sdf_params, d_color_params, d_embedding_params;
  field.BackwardBatch(sdf_params, color_params, field_batch, d_sdf, d_rgb, {0, total_samples},
                      &d_sdf_params, &d_color_params);
  (*mlp_gradient)[0] = d_sdf_params.col(0);
  (*mlp_gradient)[1] = d_color_params.col(0);
  (*mlp_gradient)[2] = Eigen::VectorXd::Zero(model.embedding_size());
  Eigen::MatrixXd d_psi;
  if (total_match > 0) {
    MatchPsiCotangent(0, &d_psi);
    field.BackwardEmbeddingBatch(embedding_params, match_batch, d_psi, {0, total_match},
                                 &d_embedding_params);
    (*mlp_gradient)[2] += d_embedding_params.col(0);
  }
  if (total_emb > 0) {
    SamplePsiCotangent(0, &d_psi);
    field.BackwardEmbeddingBatch(embedding_params, sample_batch, d_psi, {0, total_emb},
                                 &d_embedding_params);
    (*mlp_gradient)[2] += d_embedding_params.col(0);
  }
  if (delta != nullptr) {
    Eigen::MatrixXd d_bw, d_fw, g;
    GatherDeltaAdjoints(scratch, fw_groups, num_bones, 0, &d_bw, &d_fw, nullptr);
    delta->BackwardBatch(delta_params, backward_delta, d_bw, {0, total_samples}, &g);
    (*mlp_gradient)[3] = g.col(0);
    if (total_fw > 0) {
      delta->BackwardBatch(delta_params, forward_delta, d_fw, {0, total_fw}, &g);
      (*mlp_gradient)[3] += g.col(0);
    }
  }
}

// Pass 4 (batched): MLP weight Jacobians, one backward pass per residual
// row over the whole minibatch, grouped per ray.
void RayPipeline::MlpJacobians() {
  int max_rows = 0;
  for (const RayScratch& s : scratch) max_rows = std::max(max_rows, s.composite_rows);
  Eigen::VectorXd d_sdf(total_samples);
  Eigen::Matrix3Xd d_rgb(3, total_samples);
  Eigen::MatrixXd d_sdf_params, d_color_params, d_embedding_params, d_psi;
  for (int k = 0; k < max_rows; ++k) {
    d_sdf.setZero();
    d_rgb.setZero();
    bool any_field = false;
    bool any_match = false;
    bool any_emb = false;
    for (int r = 0; r < num_rays; ++r) {
      const RayScratch& s = scratch[r];
      if (k >= s.composite_rows) continue;
      for (int i = 0; i < s.num_samples; ++i) {
        d_sdf(s.field_offset + i) = s.a_sdf(k, i);
        for (int c = 0; c < 3; ++c) d_rgb(c, s.field_offset + i) = s.a_rgb(k, 3 * i + c);
      }
      any_field = any_field || s.a_sdf.row(k).squaredNorm() > 0 || s.a_rgb.row(k).squaredNorm() > 0;
      any_match = any_match || (s.num_match > 0 && s.a_xhat.row(k).squaredNorm() > 0);
      any_emb = any_emb || (s.num_emb > 0 && s.a_psi.row(k).squaredNorm() > 0);
    }
    if (any_field) {
      field.BackwardBatch(sdf_params, color_params, field_batch, d_sdf, d_rgb, field_groups,
                          &d_sdf_params, &d_color_params);
      for (int r = 0; r < num_rays; ++r) {
        if (k >= scratch[r].composite_rows) continue;
        (*out)[r].jacobians[kBlockSdf].row(k) = d_sdf_params.col(r).transpose();
        (*out)[r].jacobians[kBlockColor].row(k) = d_color_params.col(r).transpose();
      }
    }
    if (any_match) {
      MatchPsiCotangent(k, &d_psi);
      field.BackwardEmbeddingBatch(embedding_params, match_batch, d_psi, match_groups,
                                   &d_embedding_params);
      for (int r = 0; r < num_rays; ++r) {
        if (k >= scratch[r].composite_rows || scratch[r].num_match == 0) continue;
        (*out)[r].jacobians[kBlockEmbedding].row(k) = d_embedding_params.col(r).transpose();
      }
    }
    if (any_emb) {
      SamplePsiCotangent(k, &d_psi);
      field.BackwardEmbeddingBatch(embedding_params, sample_batch, d_psi, emb_groups,
                                   &d_embedding_params);
      for (int r = 0; r < num_rays; ++r) {
        if (k >= scratch[r].composite_rows || scratch[r].num_emb == 0) continue;
        (*out)[r].jacobians[kBlockEmbedding].row(k) += d_embedding_params.col(r).transpose();
      }
    }
    if (delta != nullptr) {
      Eigen::MatrixXd d_bw, d_fw, g_bw, g_fw;
      bool any = false;
      GatherDeltaAdjoints(scratch, fw_groups, num_bones, k, &d_bw, &d_fw, &any);
      if (any) {
        delta->BackwardBatch(delta_params, backward_delta, d_bw, field_groups, &g_bw);
        if (total_fw > 0) delta->BackwardBatch(delta_params, forward_delta, d_fw, fw_groups, &g_fw);
        for (int r = 0; r < num_rays; ++r) {
          if (k >= scratch[r].composite_rows) continue;
          auto row = (*out)[r].jacobians[kBlockDeltaSkin].row(k);
          row = g_bw.col(r).transpose();
          if (total_fw > 0) row += g_fw.col(r).transpose();
        }
      }
    }
  }
}

// MLP_Delta weight Jacobians of the 3D-cycle rows: row (i, c) of a ray
// depends on two batch columns only (the backward warp at sample i, the
// forward warp of X*_i), so for each sample index i the rays' two columns
// are re-evaluated as a compact batch (one group per ray) and differentiated
// once per coordinate c, instead of a pass over the whole minibatch per row.
void RayPipeline::DeltaCycle3dJacobians() {
  if (delta == nullptr) return;
  {
    int max_n = 0;
    for (const RayScratch& s : scratch) {
      if (s.c3_dbw.rows() > 0) max_n = std::max(max_n, s.num_samples);
    }
    for (int i = 0; i < max_n; ++i) {
      std::vector<int> members;
      for (int r = 0; r < num_rays; ++r) {
        if (scratch[r].c3_dbw.rows() > 0 && i < scratch[r].num_samples) members.push_back(r);
      }
      const int m = static_cast<int>(members.size());
      DeltaSkinningBatch cb, cf;
      cb.x.resize(3, m);
      cb.codes.resize(pose_code_dim, m);
      cf.x.resize(3, m);
      cf.codes.resize(pose_code_dim, m);
      for (int j = 0; j < m; ++j) {
        const RayScratch& s = scratch[members[j]];
        cb.x.col(j) = backward_delta.x.col(s.field_offset + i);
        cb.codes.col(j) = backward_delta.codes.col(s.field_offset + i);
        cf.x.col(j) = forward_delta.x.col(s.fw_offset + i);
        cf.codes.col(j) = forward_delta.codes.col(s.fw_offset + i);
      }
      delta->ForwardBatch(delta_params, &cb, false);
      delta->ForwardBatch(delta_params, &cf, false);
      std::vector<int> groups(m + 1);
      for (int j = 0; j <= m; ++j) groups[j] = j;
      Eigen::MatrixXd d_b(num_bones, m), d_f(num_bones, m), g_b, g_f;
      for (int c = 0; c < 3; ++c) {
        for (int j = 0; j < m; ++j) {
          const RayScratch& s = scratch[members[j]];
          d_b.col(j) = s.c3_dbw.row(3 * i + c).transpose();
          d_f.col(j) = s.c3_dfw.row(3 * i + c).transpose();
        }
        delta->BackwardBatch(delta_params, cb, d_b, groups, &g_b);
        delta->BackwardBatch(delta_params, cf, d_f, groups, &g_f);
        for (int j = 0; j < m; ++j) {
          RayEvaluation& ev = (*out)[members[j]];
          const int row = ev.term_row[static_cast<int>(LossTerm::kCycle3d)] + 3 * i + c;
          ev.jacobians[kBlockDeltaSkin].row(row) = (g_b.col(j) + g_f.col(j)).transpose();
        }
      }
    }
  }
}

}  // namespace banmo
