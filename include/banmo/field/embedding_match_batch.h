// Batched canonical-embedding matching (BANMo Eq. 15) for a minibatch of
// pixels, with per-pixel gradients wrt the embedding MLP's weights: the
// pieces a feature-matching residual (Eq. 17) needs from the field module.
//
//   1. once per minibatch: psi on the canonical grid (ForwardEmbeddingBatch)
//      and EmbeddingMatcher::Build;
//   2. MatchEmbeddingBatch: top-K soft-argmax X_hat for every pixel, and the
//      embedding MLP's cache at each pixel's K neighbours (concatenated, one
//      group per pixel);
//   3. per residual row, MatchEmbeddingBackward: given d(row)/d X_hat for
//      every pixel (3 x P), the per-pixel gradient of that row wrt the
//      embedding weights (P_emb x P), via the hand-written soft-argmax
//      backward and Mlp::Backward with one group per pixel.
// The top-K neighbour set is treated as constant (piecewise constant in the
// weights), as in any truncated soft-argmax.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "banmo/field/canonical_field.h"
#include "banmo/field/embedding_match.h"

namespace banmo {

struct EmbeddingMatchBatch {
  // Input: pixel features, 16 x P.
  Eigen::MatrixXd features;
  // Outputs.
  std::vector<MatchResult> matches;  // per pixel (indices, weights, x_hat)
  Eigen::Matrix3Xd x_hat;            // 3 x P
  // Pixel p's neighbours are samples [group_begin[p], group_begin[p+1]) of
  // `neighbours` (x = their grid points, in MatchResult::indices order).
  std::vector<int> group_begin;
  EmbeddingBatch neighbours;

  int size() const { return static_cast<int>(features.cols()); }
};

// Matches every pixel (k neighbours each, parallel over pixels) and runs the
// embedding MLP forward on the gathered neighbours. `matcher` must have been
// built from psi computed with the same `params`.
void MatchEmbeddingBatch(const CanonicalField& field, const double* params,
                         const EmbeddingMatcher& matcher, int k, EmbeddingMatchBatch* batch);

// d_params (P_emb x P): column p = (d x_hat_p / d params)^T d_x_hat.col(p).
// d_features (may be null): 16 x P, gradient wrt the pixel features.
void MatchEmbeddingBackward(const CanonicalField& field, const double* params,
                            const EmbeddingMatcher& matcher, const EmbeddingMatchBatch& batch,
                            const Eigen::Matrix3Xd& d_x_hat, Eigen::MatrixXd* d_params,
                            Eigen::MatrixXd* d_features = nullptr);

}  // namespace banmo
