#include "banmo/field/embedding_match_batch.h"

#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

void MatchEmbeddingBatch(const CanonicalField& field, const double* params,
                         const EmbeddingMatcher& matcher, int k, EmbeddingMatchBatch* batch) {
  CHECK(batch != nullptr);
  CHECK_EQ(batch->features.rows(), kEmbeddingFeatureDim);
  const int P = batch->size();
  batch->matches.resize(P);
  ParallelFor(P, [&](int begin, int end) {
    for (int p = begin; p < end; ++p) {
      matcher.Match(Eigen::VectorXd(batch->features.col(p)), k, &batch->matches[p]);
    }
  });
  batch->x_hat.resize(3, P);
  batch->group_begin.assign(1, 0);
  for (int p = 0; p < P; ++p) {
    batch->x_hat.col(p) = batch->matches[p].x_hat;
    batch->group_begin.push_back(batch->group_begin.back() +
                                 static_cast<int>(batch->matches[p].indices.size()));
  }
  batch->neighbours.x.resize(3, batch->group_begin.back());
  for (int p = 0; p < P; ++p) {
    const std::vector<int>& idx = batch->matches[p].indices;
    for (size_t i = 0; i < idx.size(); ++i) {
      batch->neighbours.x.col(batch->group_begin[p] + static_cast<int>(i)) =
          matcher.grid().col(idx[i]);
    }
  }
  field.ForwardEmbeddingBatch(params, &batch->neighbours, false);
}

void MatchEmbeddingBackward(const CanonicalField& field, const double* params,
                            const EmbeddingMatcher& matcher, const EmbeddingMatchBatch& batch,
                            const Eigen::Matrix3Xd& d_x_hat, Eigen::MatrixXd* d_params,
                            Eigen::MatrixXd* d_features) {
  const int P = batch.size();
  CHECK_EQ(d_x_hat.cols(), P);
  CHECK_EQ(static_cast<int>(batch.group_begin.size()), P + 1) << "call MatchEmbeddingBatch first";
  const int n = batch.group_begin.back();
  CHECK_EQ(batch.neighbours.cache.num_samples(), n);
  Eigen::MatrixXd d_psi(kEmbeddingFeatureDim, n);
  if (d_features != nullptr) d_features->resize(kEmbeddingFeatureDim, P);
  const double temperature = matcher.options().temperature;
  ParallelFor(P, [&](int begin, int end) {
    Eigen::MatrixXd psi, points, d_psi_p;
    Eigen::VectorXd d_f;
    for (int p = begin; p < end; ++p) {
      const std::vector<int>& idx = batch.matches[p].indices;
      const int K = static_cast<int>(idx.size());
      // The psi the match used (the matcher's grid values).
      psi.resize(kEmbeddingFeatureDim, K);
      points.resize(3, K);
      for (int i = 0; i < K; ++i) {
        psi.col(i) = matcher.psi().col(idx[i]);
        points.col(i) = matcher.grid().col(idx[i]);
      }
      const Eigen::VectorXd f = batch.features.col(p);
      const Eigen::Vector3d g = d_x_hat.col(p);
      SoftArgmaxBackward(f.data(), psi.data(), points.data(), K, temperature, g.data(), &d_psi_p,
                         d_features != nullptr ? &d_f : nullptr);
      d_psi.middleCols(batch.group_begin[p], K) = d_psi_p;
      if (d_features != nullptr) d_features->col(p) = d_f;
    }
  });
  field.BackwardEmbeddingBatch(params, batch.neighbours, d_psi, batch.group_begin, d_params);
}

}  // namespace banmo
