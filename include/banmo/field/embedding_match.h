// Canonical-embedding matching, BANMo (Yang et al. 2022) Eq. 15: a pixel
// feature f (16) is matched to the canonical space by a soft-argmax of the
// cosine similarity between f and the canonical embedding psi on a canonical
// grid G (3 x M):
//   s_m = cos(f, psi_m),  w = softmax(temperature * s),  X_hat = sum_m w_m G_m.
// The sum is truncated to the pixel's K most similar grid points, found with
// a FLANN index over the normalised psi (Euclidean distance between unit
// vectors is monotone in the cosine: |a - b|^2 = 2 - 2 cos(a, b)). The index
// is built once per minibatch (psi changes with the embedding MLP weights).
//
// Cosine similarity is computed in a safe, smooth form
//   cos(a, b) = a.b / (sqrt(|a|^2 + eps^2) sqrt(|b|^2 + eps^2)),  eps = 1e-8
// so zero-norm features or embeddings give similarity 0 (uniform weights),
// never NaN; for |a|, |b| >> eps it equals the cosine to ~eps^2 / |a|^2.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace banmo {

inline constexpr int kEmbeddingFeatureDim = 16;
inline constexpr double kCosineEps = 1e-8;

struct EmbeddingMatcherOptions {
  // Softmax temperature alpha_s (> 0) multiplying the cosine similarity (in
  // [-1, 1]); the paper learns it. It decides how much mass the top-K
  // truncation drops: measured on M = 4096 grid points with a smooth random
  // embedding (tests/field/embedding_match_test.cc, TopKTruncationError),
  // the mean softmax mass outside the top 64 is 0.67 at 10, 0.37 at 20 and
  // 0.067 at 50 (mean |X_top64 - X_full| = 0.17, 0.057, 0.0086 in a [-1,1]^3
  // grid). Use >= 50 with K = 64 when the truncation should be negligible.
  double temperature = 50.0;
  // Exact top-K search (brute force over all M grid points). Otherwise FLANN
  // randomised kd-trees (approximate).
  bool exact = false;
  // Number of randomised kd-trees (> 0) when !exact.
  int num_kdtrees = 4;
  // FLANN search checks (leaves visited, > 0) when !exact; higher = closer to
  // the exact top-K.
  int checks = 256;

  // Throws InputError naming the field under `key` unless the options are
  // valid.
  void Check(const std::string& key = "matcher") const;
};

struct MatchResult {
  std::vector<int> indices;                         // K grid indices, most similar first
  Eigen::VectorXd similarity;                       // K safe cosine similarities
  Eigen::VectorXd weights;                          // K softmax weights (sum to 1)
  Eigen::Vector3d x_hat = Eigen::Vector3d::Zero();  // sum_k weights_k G_k
};

// Safe cosine similarity (see file comment), any scalar type.
template <typename T>
T SafeCosine(const T* a, const T* b, int dim) {
  using std::sqrt;
  T ab(0.0), aa(0.0), bb(0.0);
  for (int i = 0; i < dim; ++i) {
    ab += a[i] * b[i];
    aa += a[i] * a[i];
    bb += b[i] * b[i];
  }
  const double eps2 = kCosineEps * kCosineEps;
  return ab / (sqrt(aa + eps2) * sqrt(bb + eps2));
}

// Reference soft-argmax over K candidates: feature (16), psi (16 x K,
// column-major, column k = candidate k), points (3 x K column-major, grid
// positions, constant), temperature > 0. x_hat: 3 values. T may be a
// ceres::Jet (derivatives wrt feature and psi); Temp is double or T (a
// learnable temperature).
template <typename T, typename Temp>
void SoftArgmax(const T* feature, const T* psi, const double* points, int K,
                const Temp& temperature, T* x_hat) {
  using std::exp;
  std::vector<T> logits(K);
  int best = 0;
  for (int k = 0; k < K; ++k) {
    logits[k] =
        temperature * SafeCosine(feature, psi + kEmbeddingFeatureDim * k, kEmbeddingFeatureDim);
    if (logits[k] > logits[best]) best = k;
  }
  // Log-sum-exp safe softmax (the shift cancels exactly in value and
  // derivative).
  const T shift = logits[best];
  T total(0.0);
  for (int k = 0; k < K; ++k) {
    logits[k] = exp(logits[k] - shift);
    total += logits[k];
  }
  for (int c = 0; c < 3; ++c) x_hat[c] = T(0.0);
  for (int k = 0; k < K; ++k) {
    const T w = logits[k] / total;
    for (int c = 0; c < 3; ++c) x_hat[c] += w * points[3 * k + c];
  }
}

// Exact hand-written backward of SoftArgmax (double): given d_x_hat (3),
// returns d_psi (16 x K, column k = dL/dpsi_k) and, if not null, d_feature
// (16) and d_temperature (1). Inputs as in SoftArgmax.
void SoftArgmaxBackward(const double* feature, const double* psi, const double* points, int K,
                        double temperature, const double* d_x_hat, Eigen::MatrixXd* d_psi,
                        Eigen::VectorXd* d_feature, double* d_temperature = nullptr);

class EmbeddingMatcher {
 public:
  explicit EmbeddingMatcher(const EmbeddingMatcherOptions& options = {});
  ~EmbeddingMatcher();
  EmbeddingMatcher(const EmbeddingMatcher&) = delete;
  EmbeddingMatcher& operator=(const EmbeddingMatcher&) = delete;

  const EmbeddingMatcherOptions& options() const { return options_; }

  // grid: 3 x M canonical points; psi: 16 x M embeddings at those points.
  // Builds the search index (once per minibatch).
  void Build(const Eigen::Matrix3Xd& grid, const Eigen::MatrixXd& psi);

  int NumPoints() const { return static_cast<int>(grid_.cols()); }
  const Eigen::Matrix3Xd& grid() const { return grid_; }
  const Eigen::MatrixXd& psi() const { return psi_; }

  // Top-k soft-argmax of one pixel feature (16) with options().temperature
  // (k is clamped to M). Thread-safe after Build.
  void Match(const Eigen::VectorXd& feature, int k, MatchResult* result) const;
  void Match(const Eigen::VectorXf& feature, int k, MatchResult* result) const;

  // Untruncated soft-argmax over all M grid points (the reference for the
  // truncation error); result->indices lists all M points, most similar
  // first.
  void MatchFull(const Eigen::VectorXd& feature, MatchResult* result) const;

 private:
  void FinishMatch(const Eigen::VectorXd& feature, std::vector<int> indices,
                   MatchResult* result) const;

  struct Index;
  EmbeddingMatcherOptions options_;
  Eigen::Matrix3Xd grid_;
  Eigen::MatrixXd psi_;
  std::vector<float> normalized_psi_;  // 16 x M, row per point for FLANN
  std::unique_ptr<Index> index_;
};

}  // namespace banmo
