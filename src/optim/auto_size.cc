#include "banmo/optim/auto_size.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "banmo/deform/bones.h"
#include "banmo/field/mlp_widen.h"
#include "banmo/losses/ray_functors.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

// Tangent sizes per bone of the "bones" (quaternion block manifold) and
// "bones_t" (stacked pose manifold) blocks, see geometry/pose_manifold.h.
constexpr int kBoneTangent = kBoneSize - 1;
constexpr int kPoseTangent = 6;

Eigen::Matrix3d BoneRotation(const double* bone) {
  Eigen::Quaterniond q(bone[kBoneQw], bone[kBoneQw + 1], bone[kBoneQw + 2], bone[kBoneQw + 3]);
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3d BoneCovariance(const double* bone) {
  const Eigen::Matrix3d r = BoneRotation(bone);
  Eigen::Vector3d var;
  for (int k = 0; k < 3; ++k) var[k] = std::exp(2.0 * bone[kBoneLogScale + k]);
  return r * var.asDiagonal() * r.transpose();
}

// A bone with centre c and covariance s (orientation and log-scales from
// its eigen-decomposition).
void BoneFromCovariance(const Eigen::Vector3d& c, const Eigen::Matrix3d& s, double* bone) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (s + s.transpose()));
  Eigen::Matrix3d r = eig.eigenvectors();
  if (r.determinant() < 0) r.col(2) *= -1.0;
  const Eigen::Quaterniond q(r);
  for (int k = 0; k < 3; ++k) bone[kBoneCenter + k] = c[k];
  bone[kBoneQw] = q.w();
  bone[kBoneQw + 1] = q.x();
  bone[kBoneQw + 2] = q.y();
  bone[kBoneQw + 3] = q.z();
  for (int k = 0; k < 3; ++k) {
    bone[kBoneLogScale + k] = 0.5 * std::log(std::max(eig.eigenvalues()[k], 1e-300));
  }
}

// Backward skinning weights and the backward warp of x_in_root at a frame.
void BackwardWeights(int num_bones, const double* bones, const double* bones_t,
                     const Eigen::Vector3d& x, double* weights, Eigen::Vector3d* canonical) {
  std::vector<double> logits(num_bones), points(3 * num_bones);
  for (int b = 0; b < num_bones; ++b) {
    BackwardBoneTerm(bones + kBoneSize * b, bones_t + kPoseSize * b, x.data(), &logits[b],
                     &points[3 * b]);
  }
  SkinningWeights(num_bones, logits.data(), weights);
  canonical->setZero();
  for (int b = 0; b < num_bones; ++b) {
    *canonical += weights[b] * Eigen::Vector3d(points[3 * b], points[3 * b + 1], points[3 * b + 2]);
  }
}

// Per-bone chunks of a stacked block: new chunk n copies old chunk
// new_to_old[n].
TangentRemap ChunkRemap(const std::vector<int>& new_to_old, int chunk) {
  TangentRemap r;
  for (int n = 0; n < static_cast<int>(new_to_old.size()); ++n) {
    for (int k = 0; k < chunk; ++k) {
      r.source.push_back(chunk * new_to_old[n] + k);
      r.scale.push_back(1.0);
    }
  }
  return r;
}

// Principal axis of sum_r w_r (X_r - c)(X_r - c)^T (the error around the
// bone centre), or the bone's longest axis if the weights vanish.
Eigen::Vector3d SplitDirection(const double* bone, const std::vector<SurfacePoint>& points, int b) {
  const Eigen::Vector3d c(bone[0], bone[1], bone[2]);
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  double total = 0.0;
  for (const SurfacePoint& p : points) {
    const double w = p.error * p.attribution[b];
    const Eigen::Vector3d d = p.canonical - c;
    m += w * d * d.transpose();
    total += w;
  }
  if (total > 1e-300 && m.trace() > 1e-20 * total) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m / total);
    return eig.eigenvectors().col(2);
  }
  int longest = 0;
  for (int k = 1; k < 3; ++k) {
    if (bone[kBoneLogScale + k] > bone[kBoneLogScale + longest]) longest = k;
  }
  return BoneRotation(bone).col(longest);
}

// The points the warp change is measured on: rays through the surface
// (opacity >= 0.5), or all rays if fewer than 8 are.
std::vector<SurfacePoint> MeasurePoints(const std::vector<SurfacePoint>& points) {
  std::vector<SurfacePoint> out;
  for (const SurfacePoint& p : points) {
    if (p.opacity >= 0.5) out.push_back(p);
  }
  return out.size() >= 8 ? out : points;
}

}  // namespace

BoneSet BoneSet::Of(const Model& model) {
  BoneSet s;
  s.num_bones = model.num_bones();
  s.bones.assign(model.bones(), model.bones() + model.bones_size());
  s.bones_t.resize(model.num_videos());
  for (int v = 0; v < model.num_videos(); ++v) {
    for (const FrameParameters& f : model.video(v).frames) s.bones_t[v].push_back(f.bones_t);
  }
  return s;
}

void BoneSet::WriteTo(Model* model) const {
  CHECK_EQ(static_cast<int>(bones_t.size()), model->num_videos());
  model->SetBones(num_bones, bones);
  for (int v = 0; v < model->num_videos(); ++v) {
    CHECK_EQ(bones_t[v].size(), model->video(v).frames.size());
    for (size_t t = 0; t < bones_t[v].size(); ++t) model->frame(v, t).bones_t = bones_t[v][t];
  }
}

std::vector<SurfacePoint> SurfacePoints(const Model& model, const std::vector<Ray>& rays,
                                        const std::vector<RayEvaluation>& evaluations) {
  CHECK_EQ(rays.size(), evaluations.size());
  const int B = model.num_bones();
  std::vector<SurfacePoint> out(rays.size());
  ParallelFor(static_cast<int>(rays.size()), [&](int begin, int end) {
    std::vector<double> w(B);
    for (int r = begin; r < end; ++r) {
      const Ray& ray = rays[r];
      const RayEvaluation& ev = evaluations[r];
      SurfacePoint& p = out[r];
      p.video = ray.video;
      p.frame = ray.frame;
      p.mask = ray.mask;
      p.attribution.assign(B, 0.0);
      for (LossTerm term : {LossTerm::kRgb, LossTerm::kSilhouette}) {
        const int row = ev.term_row[static_cast<int>(term)];
        if (row < 0) continue;
        for (int k = 0; k < LossTermResiduals(term, ray.NumSamples()); ++k) {
          p.error += ev.residuals[row + k] * ev.residuals[row + k];
        }
      }
      const FrameParameters& f = model.frame(ray.video, ray.frame);
      const double* intrinsics = model.video(ray.video).intrinsics.data();
      const int n = ray.NumSamples();
      CHECK_EQ(static_cast<int>(ev.tau.size()), n);
      double total = 0.0;
      for (int i = 0; i < n; ++i) {
        const double omega = std::max(ev.tau[i], 0.0) + 1e-3 / n;
        p.opacity += ev.tau[i];
        Eigen::Vector3d x;
        SampleInRoot(f.root_delta.data(), f.root_init.data(), intrinsics, ray.uv.data(),
                     ray.samples.depths[i], x.data());
        Eigen::Vector3d canonical = x;
        if (B > 0) BackwardWeights(B, model.bones(), f.bones_t.data(), x, w.data(), &canonical);
        p.posed += omega * x;
        p.canonical += omega * canonical;
        for (int b = 0; b < B; ++b) p.attribution[b] += omega * w[b];
        total += omega;
      }
      p.posed /= total;
      p.canonical /= total;
      for (double& a : p.attribution) a /= total;
    }
  });
  return out;
}

BoneAttribution AttributeErrors(const std::vector<SurfacePoint>& points, int num_bones) {
  BoneAttribution a;
  a.mass_share.assign(num_bones, 0.0);
  a.error_share.assign(num_bones, 0.0);
  a.ratio.assign(num_bones, 0.0);
  double total_error = 0.0;
  for (const SurfacePoint& p : points) {
    total_error += p.error;
    for (int b = 0; b < num_bones; ++b) {
      a.mass_share[b] += p.attribution[b];
      a.error_share[b] += p.error * p.attribution[b];
    }
  }
  const double rays = std::max<double>(1.0, points.size());
  a.mean_error = total_error / rays;
  for (int b = 0; b < num_bones; ++b) {
    a.mass_share[b] /= rays;
    a.error_share[b] = total_error > 0 ? a.error_share[b] / total_error : 0.0;
    a.ratio[b] = a.mass_share[b] > 0 ? a.error_share[b] / a.mass_share[b] : 0.0;
  }
  return a;
}

std::vector<SurfacePoint> ObjectRays(const std::vector<SurfacePoint>& points) {
  std::vector<SurfacePoint> out;
  for (const SurfacePoint& p : points) {
    if (p.mask > 0.5 || p.opacity >= 0.5) out.push_back(p);
  }
  return out;
}

void SplitBoneGeometry(const double* bone, const Eigen::Vector3d& direction, double offset,
                       double* first, double* second) {
  CHECK(offset > 0 && offset < 1) << offset;
  CHECK_GT(direction.norm(), 0.0);
  const Eigen::Vector3d u = direction.normalized();
  const Eigen::Matrix3d s = BoneCovariance(bone);
  const double sigma2 = 1.0 / (u.dot(s.inverse() * u));  // variance along u given the rest
  const Eigen::Matrix3d copy = s - offset * offset * sigma2 * u * u.transpose();
  const Eigen::Vector3d c(bone[0], bone[1], bone[2]);
  const Eigen::Vector3d d = offset * std::sqrt(sigma2) * u;
  BoneFromCovariance(c - d, copy, first);
  BoneFromCovariance(c + d, copy, second);
}

BoneSet SplitBones(const BoneSet& in, const std::vector<BoneSplit>& splits,
                   std::vector<int>* new_to_old) {
  BoneSet out = in;
  std::vector<int> source(in.num_bones);
  std::iota(source.begin(), source.end(), 0);
  for (const BoneSplit& split : splits) {
    const int b = split.bone;
    CHECK(b >= 0 && b < in.num_bones);
    std::vector<double> second(kBoneSize);
    SplitBoneGeometry(in.bones.data() + kBoneSize * b, split.direction, split.offset,
                      out.bones.data() + kBoneSize * b, second.data());
    out.bones.insert(out.bones.end(), second.begin(), second.end());
    source.push_back(b);
  }
  out.num_bones = static_cast<int>(source.size());
  for (auto& video : out.bones_t) {
    for (std::vector<double>& f : video) {
      CHECK_EQ(static_cast<int>(f.size()), kPoseSize * in.num_bones);
      for (const BoneSplit& split : splits) {
        const std::vector<double> pose(f.begin() + kPoseSize * split.bone,
                                       f.begin() + kPoseSize * (split.bone + 1));
        f.insert(f.end(), pose.begin(), pose.end());
      }
    }
  }
  if (new_to_old != nullptr) *new_to_old = source;
  return out;
}

WarpChange MeasureWarpChange(const BoneSet& before, const BoneSet& after,
                             const std::vector<SurfacePoint>& points) {
  WarpChange c;
  c.points = static_cast<int>(points.size());
  if (points.empty()) return c;
  std::vector<double> backward(points.size()), forward(points.size());
  ParallelFor(c.points, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      const SurfacePoint& p = points[i];
      const std::vector<double>& t0 = before.bones_t[p.video][p.frame];
      const std::vector<double>& t1 = after.bones_t[p.video][p.frame];
      Eigen::Vector3d b0, b1, f0, f1;
      BackwardWarp(before.num_bones, before.bones.data(), t0.data(), p.posed.data(), b0.data());
      BackwardWarp(after.num_bones, after.bones.data(), t1.data(), p.posed.data(), b1.data());
      ForwardWarp(before.num_bones, before.bones.data(), t0.data(), p.canonical.data(), f0.data());
      ForwardWarp(after.num_bones, after.bones.data(), t1.data(), p.canonical.data(), f1.data());
      backward[i] = (b1 - b0).norm();
      forward[i] = (f1 - f0).norm();
    }
  });
  for (int i = 0; i < c.points; ++i) {
    c.mean_backward += backward[i] / c.points;
    c.mean_forward += forward[i] / c.points;
    c.max_backward = std::max(c.max_backward, backward[i]);
    c.max_forward = std::max(c.max_forward, forward[i]);
  }
  return c;
}

void TangentRemap::Apply(std::vector<double>* m, std::vector<double>* v) const {
  if (m->empty() && v->empty()) return;
  std::vector<double> m2(source.size()), v2(source.size());
  for (size_t k = 0; k < source.size(); ++k) {
    CHECK_LT(static_cast<size_t>(source[k]), m->size());
    m2[k] = scale[k] * (*m)[source[k]];
    v2[k] = scale[k] * scale[k] * (*v)[source[k]];
  }
  *m = std::move(m2);
  *v = std::move(v2);
}

const TangentRemap* AutoSizeRemaps::For(const std::string& block_name) const {
  std::string group = block_name;
  const std::string suffix = "/bones_t";
  if (block_name.size() > suffix.size() &&
      block_name.compare(block_name.size() - suffix.size(), suffix.size(), suffix) == 0) {
    group = "bones_t";
  }
  const auto it = by_group.find(group);
  return it == by_group.end() ? nullptr : &it->second;
}

std::string AutoSizeEvent::Describe() const {
  char buf[256];
  std::string out;
  std::snprintf(buf, sizeof(buf),
                "auto-size at batch %d: %d rays (%d on the object), mean error %.4g", batch, rays,
                object_rays, mean_error);
  out += buf;
  const std::vector<double>& ratio = attribution.ratio;
  if (!ratio.empty()) {
    const int top = static_cast<int>(std::max_element(ratio.begin(), ratio.end()) - ratio.begin());
    std::snprintf(buf, sizeof(buf), ", largest ratio %.2f (bone %d, %.0f %% of the rays)",
                  ratio[top], top, 100.0 * attribution.mass_share[top]);
    out += buf;
  }
  out += "; ";
  if (!splits.empty()) {
    std::snprintf(buf, sizeof(buf), "bones %d -> %d (split", bones_before, bones_after);
    out += buf;
    for (size_t i = 0; i < splits.size(); ++i) {
      std::snprintf(buf, sizeof(buf), " %d: ratio %.2f a %.2f%s", splits[i].bone, split_ratios[i],
                    splits[i].offset, i + 1 < splits.size() ? "," : "");
      out += buf;
    }
    std::snprintf(buf, sizeof(buf),
                  "); warp change on %d points: backward mean %.2e max %.2e, forward mean %.2e "
                  "max %.2e",
                  warp.points, warp.mean_backward, warp.max_backward, warp.mean_forward,
                  warp.max_forward);
    out += buf;
  } else if (sdf_width_after != sdf_width_before || color_width_after != color_width_before) {
    std::snprintf(buf, sizeof(buf),
                  "no bone split; widths sdf %d -> %d, color %d -> %d (sdf change mean %.2e max "
                  "%.2e)",
                  sdf_width_before, sdf_width_after, color_width_before, color_width_after,
                  sdf_change_mean, sdf_change_max);
    out += buf;
  } else {
    std::snprintf(buf, sizeof(buf), "no growth (%d bones, widths %d / %d)", bones_after,
                  sdf_width_after, color_width_after);
    out += buf;
  }
  if (seconds > 0) {
    std::snprintf(buf, sizeof(buf), " [%.2f s]", seconds);
    out += buf;
  }
  return out;
}

AutoSizeEvent AutoSizeGrow(const AutoSizeOptions& options, const RaySampler& sampler,
                           const SamplingConfig& sampling, int samples_per_ray,
                           const Eigen::AlignedBox3d& bounds, std::mt19937* rng, Model* model,
                           AutoSizeRemaps* remaps) {
  AutoSizeEvent event;
  remaps->by_group.clear();
  const int B = model->num_bones();
  event.bones_before = event.bones_after = B;
  event.sdf_width_before = event.sdf_width_after = model->options().field.sdf_width;
  event.color_width_before = event.color_width_after = model->options().field.color_width;

  // 1. Evaluation rays, rgb and silhouette only.
  SamplingConfig eval_sampling = sampling;
  eval_sampling.active_fraction = 0.0;
  std::vector<Ray> rays =
      sampler.Sample(options.eval_rays, samples_per_ray, eval_sampling, *model, bounds, rng);
  RayBatchOptions batch_options;
  batch_options.weights = RayLossWeights::Only({LossTerm::kRgb, LossTerm::kSilhouette});
  batch_options.matcher.exact = true;
  std::vector<RayEvaluation> evaluations;
  {
    RayBatch batch(model, batch_options);
    batch.SetRays(rays);
    batch.EvaluateAll(false);
    for (int r = 0; r < batch.num_rays(); ++r) evaluations.push_back(batch.evaluation(r));
  }
  const std::vector<SurfacePoint> all = SurfacePoints(*model, rays, evaluations);
  const std::vector<SurfacePoint> points = ObjectRays(all);
  event.rays = static_cast<int>(all.size());
  event.object_rays = static_cast<int>(points.size());
  event.attribution = AttributeErrors(points, B);
  event.mean_error = event.attribution.mean_error;
  const std::vector<SurfacePoint> measure = MeasurePoints(all);

  // 2. Bone splits, largest ratio first.
  const BoneSet before = BoneSet::Of(*model);
  std::vector<int> order(B);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return event.attribution.ratio[a] > event.attribution.ratio[b];
  });
  for (int b : order) {
    if (B + static_cast<int>(event.splits.size()) >= options.max_bones) break;
    if (event.attribution.ratio[b] < options.error_ratio) break;
    if (event.attribution.mass_share[b] * event.object_rays < kMinSplitRays) continue;
    BoneSplit split;
    split.bone = b;
    split.direction = SplitDirection(before.bones.data() + kBoneSize * b, points, b);
    // The offset that changes the warps least (this split alone).
    double best = -1.0;
    for (double a : kSplitOffsets) {
      BoneSplit candidate = split;
      candidate.offset = a;
      const WarpChange c = MeasureWarpChange(before, SplitBones(before, {candidate}), measure);
      const double score = c.mean_backward + c.mean_forward;
      if (best < 0 || score < best) {
        best = score;
        split.offset = a;
      }
    }
    event.splits.push_back(split);
    event.split_ratios.push_back(event.attribution.ratio[b]);
  }
  if (!event.splits.empty()) {
    std::vector<int> new_to_old;
    const BoneSet after = SplitBones(before, event.splits, &new_to_old);
    event.warp = MeasureWarpChange(before, after, measure);
    after.WriteTo(model);
    event.bones_after = after.num_bones;
    remaps->by_group["bones"] = ChunkRemap(new_to_old, kBoneTangent);
    remaps->by_group["bones_t"] = ChunkRemap(new_to_old, kPoseTangent);
    return event;
  }

  // 3. No split: widen the SDF and colour MLPs.
  if (options.max_width <= 0) return event;
  auto grown = [&](int width) { return std::max(width, std::min(2 * width, options.max_width)); };
  const int sdf_width = grown(event.sdf_width_before);
  const int color_width = grown(event.color_width_before);
  if (sdf_width == event.sdf_width_before && color_width == event.color_width_before) return event;
  const CanonicalField& field = model->field();
  FieldBatch probe;
  probe.x.resize(3, static_cast<int>(measure.size()));
  for (int i = 0; i < probe.x.cols(); ++i) probe.x.col(i) = measure[i].canonical;
  field.ForwardSdfBatch(model->sdf(), &probe, false);
  const Eigen::VectorXd sdf_before = probe.sdf;
  MlpWidening sdf = WidenMlp(field.sdf_mlp(), model->sdf(), sdf_width, kWidenNoise, rng);
  MlpWidening color = WidenMlp(field.color_mlp(), model->color(), color_width, kWidenNoise, rng);
  auto remap = [](const MlpWidening& w) {
    TangentRemap r;
    r.source = w.source;
    r.scale = w.gradient_scale;
    return r;
  };
  remaps->by_group["sdf"] = remap(sdf);
  remaps->by_group["color"] = remap(color);
  model->SetFieldWidths(sdf_width, color_width, std::move(sdf.params), std::move(color.params));
  model->field().ForwardSdfBatch(model->sdf(), &probe, false);
  if (probe.size() > 0) {
    const Eigen::ArrayXd change = (probe.sdf - sdf_before).array().abs();
    event.sdf_change_mean = change.mean();
    event.sdf_change_max = change.maxCoeff();
  }
  event.sdf_width_after = sdf_width;
  event.color_width_after = color_width;
  return event;
}

}  // namespace banmo
