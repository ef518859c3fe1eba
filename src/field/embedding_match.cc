#include "banmo/field/embedding_match.h"

#include <algorithm>
#include <flann/flann.hpp>
#include <numeric>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"

namespace banmo {

void EmbeddingMatcherOptions::Check(const std::string& key) const {
  if (!(temperature > 0.0) || !std::isfinite(temperature)) {
    ThrowInputError(key, ".temperature must be finite and > 0");
  }
  if (num_kdtrees <= 0) ThrowInputError(key, ".num_kdtrees must be > 0");
  if (checks <= 0) ThrowInputError(key, ".checks must be > 0");
}

struct EmbeddingMatcher::Index {
  flann::Matrix<float> data;
  std::unique_ptr<flann::Index<flann::L2<float>>> index;
};

EmbeddingMatcher::EmbeddingMatcher(const EmbeddingMatcherOptions& options) : options_(options) {
  options_.Check();
}

EmbeddingMatcher::~EmbeddingMatcher() = default;

void EmbeddingMatcher::Build(const Eigen::Matrix3Xd& grid, const Eigen::MatrixXd& psi) {
  CHECK_EQ(psi.rows(), kEmbeddingFeatureDim);
  CHECK_EQ(psi.cols(), grid.cols());
  CHECK_GT(grid.cols(), 0) << "empty grid";
  grid_ = grid;
  psi_ = psi;
  const int M = static_cast<int>(grid.cols());
  const double eps2 = kCosineEps * kCosineEps;
  normalized_psi_.resize(static_cast<size_t>(M) * kEmbeddingFeatureDim);
  for (int m = 0; m < M; ++m) {
    const double norm = std::sqrt(psi.col(m).squaredNorm() + eps2);
    for (int d = 0; d < kEmbeddingFeatureDim; ++d) {
      normalized_psi_[static_cast<size_t>(m) * kEmbeddingFeatureDim + d] =
          static_cast<float>(psi(d, m) / norm);
    }
  }
  index_.reset();
  if (options_.exact) return;
  index_ = std::make_unique<Index>();
  index_->data = flann::Matrix<float>(normalized_psi_.data(), M, kEmbeddingFeatureDim);
  index_->index = std::make_unique<flann::Index<flann::L2<float>>>(
      index_->data, flann::KDTreeIndexParams(options_.num_kdtrees));
  index_->index->buildIndex();
}

void EmbeddingMatcher::Match(const Eigen::VectorXf& feature, int k, MatchResult* result) const {
  Match(Eigen::VectorXd(feature.cast<double>()), k, result);
}

void EmbeddingMatcher::Match(const Eigen::VectorXd& feature, int k, MatchResult* result) const {
  CHECK(result != nullptr);
  CHECK_EQ(feature.size(), kEmbeddingFeatureDim);
  const int M = NumPoints();
  CHECK_GT(M, 0) << "call Build first";
  k = std::clamp(k, 1, M);
  std::vector<int> indices;
  if (options_.exact || index_ == nullptr) {
    std::vector<double> sim(M);
    for (int m = 0; m < M; ++m) {
      sim[m] = SafeCosine(feature.data(), psi_.col(m).data(), kEmbeddingFeatureDim);
    }
    indices.resize(M);
    std::iota(indices.begin(), indices.end(), 0);
    std::partial_sort(indices.begin(), indices.begin() + k, indices.end(),
                      [&](int a, int b) { return sim[a] > sim[b] || (sim[a] == sim[b] && a < b); });
    indices.resize(k);
  } else {
    const double norm = std::sqrt(feature.squaredNorm() + kCosineEps * kCosineEps);
    std::vector<float> query(kEmbeddingFeatureDim);
    for (int d = 0; d < kEmbeddingFeatureDim; ++d) query[d] = static_cast<float>(feature[d] / norm);
    std::vector<int> found(k, -1);
    std::vector<float> dists(k);
    flann::Matrix<float> q(query.data(), 1, kEmbeddingFeatureDim);
    flann::Matrix<int> idx(found.data(), 1, k);
    flann::Matrix<float> dst(dists.data(), 1, k);
    index_->index->knnSearch(q, idx, dst, k, flann::SearchParams(options_.checks));
    for (int i : found) {
      if (i >= 0 && i < M) indices.push_back(i);
    }
    CHECK(!indices.empty()) << "FLANN returned no neighbours";
  }
  FinishMatch(feature, std::move(indices), result);
}

void EmbeddingMatcher::MatchFull(const Eigen::VectorXd& feature, MatchResult* result) const {
  CHECK(result != nullptr);
  CHECK_EQ(feature.size(), kEmbeddingFeatureDim);
  const int M = NumPoints();
  CHECK_GT(M, 0) << "call Build first";
  std::vector<int> indices(M);
  std::iota(indices.begin(), indices.end(), 0);
  FinishMatch(feature, std::move(indices), result);
}

void EmbeddingMatcher::FinishMatch(const Eigen::VectorXd& feature, std::vector<int> indices,
                                   MatchResult* result) const {
  const int K = static_cast<int>(indices.size());
  std::vector<double> sim(K);
  for (int k = 0; k < K; ++k) {
    sim[k] = SafeCosine(feature.data(), psi_.col(indices[k]).data(), kEmbeddingFeatureDim);
  }
  // Most similar first (stable tie-break on the grid index).
  std::vector<int> order(K);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return sim[a] > sim[b] || (sim[a] == sim[b] && indices[a] < indices[b]);
  });
  result->indices.resize(K);
  result->similarity.resize(K);
  result->weights.resize(K);
  for (int k = 0; k < K; ++k) {
    result->indices[k] = indices[order[k]];
    result->similarity[k] = sim[order[k]];
  }
  const double tau = options_.temperature;
  const double shift = tau * result->similarity[0];
  double total = 0.0;
  for (int k = 0; k < K; ++k) {
    result->weights[k] = std::exp(tau * result->similarity[k] - shift);
    total += result->weights[k];
  }
  result->weights /= total;
  result->x_hat.setZero();
  for (int k = 0; k < K; ++k) result->x_hat += result->weights[k] * grid_.col(result->indices[k]);
}

void SoftArgmaxBackward(const double* feature, const double* psi, const double* points, int K,
                        double temperature, const double* d_x_hat, Eigen::MatrixXd* d_psi,
                        Eigen::VectorXd* d_feature, double* d_temperature) {
  CHECK(d_psi != nullptr);
  CHECK_GT(K, 0);
  constexpr int kD = kEmbeddingFeatureDim;
  const double eps2 = kCosineEps * kCosineEps;
  const Eigen::Map<const Eigen::Matrix<double, kD, 1>> f(feature);
  const Eigen::Map<const Eigen::Matrix<double, kD, Eigen::Dynamic>> P(psi, kD, K);
  const Eigen::Map<const Eigen::Matrix3Xd> G(points, 3, K);
  const Eigen::Map<const Eigen::Vector3d> g(d_x_hat);
  const double nf = std::sqrt(f.squaredNorm() + eps2);
  Eigen::VectorXd s(K), npsi(K), w(K), u(K);
  for (int k = 0; k < K; ++k) {
    npsi[k] = std::sqrt(P.col(k).squaredNorm() + eps2);
    s[k] = f.dot(P.col(k)) / (nf * npsi[k]);
  }
  const double shift = temperature * s.maxCoeff();
  for (int k = 0; k < K; ++k) w[k] = std::exp(temperature * s[k] - shift);
  w /= w.sum();
  // x_hat = sum w_k G_k: dL/dw_k = g . G_k; softmax backward:
  // dL/ds_k = tau w_k (u_k - sum_j w_j u_j).
  for (int k = 0; k < K; ++k) u[k] = g.dot(G.col(k));
  const double u_mean = w.dot(u);
  d_psi->resize(kD, K);
  if (d_feature != nullptr) d_feature->setZero(kD);
  if (d_temperature != nullptr) *d_temperature = 0.0;
  for (int k = 0; k < K; ++k) {
    // dL/dlogit_k with logit_k = tau s_k.
    const double dlogit = w[k] * (u[k] - u_mean);
    if (d_temperature != nullptr) *d_temperature += dlogit * s[k];
    const double ds = temperature * dlogit;
    // ds_k/dpsi_k = f / (nf npsi) - s_k psi_k / npsi^2.
    d_psi->col(k) = ds * (f / (nf * npsi[k]) - s[k] * P.col(k) / (npsi[k] * npsi[k]));
    // ds_k/df = psi_k / (nf npsi) - s_k f / nf^2.
    if (d_feature != nullptr) {
      *d_feature += ds * (P.col(k) / (nf * npsi[k]) - s[k] * f / (nf * nf));
    }
  }
}

}  // namespace banmo
