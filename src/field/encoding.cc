#include "banmo/field/encoding.h"

#include <algorithm>
#include <cmath>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "banmo/util/parallel.h"

namespace banmo {

void PositionalEncodingOptions::Check(const std::string& key) const {
  // Band L has frequency 2^L: beyond 32 bands a double's sine is noise
  // (and the encoding's width, 6 per band, only costs memory).
  if (num_bands < 0 || num_bands > 32) {
    ThrowInputError(key, ".num_bands must be in [0, 32], got ", num_bands);
  }
  if (!(base_frequency > 0.0) || !std::isfinite(base_frequency)) {
    ThrowInputError(key, ".base_frequency must be finite and > 0");
  }
  if (!include_input && num_bands == 0) {
    ThrowInputError(key, ".num_bands must be > 0 when include_input is false (empty encoding)");
  }
}

PositionalEncoding::PositionalEncoding(const PositionalEncodingOptions& options)
    : options_(options) {
  options_.Check();
  band_weight_.assign(options_.num_bands, 1.0);
  band_frequency_.resize(options_.num_bands);
  for (int l = 0; l < options_.num_bands; ++l) {
    band_frequency_[l] = std::ldexp(1.0, l) * M_PI * options_.base_frequency;
  }
}

void PositionalEncoding::SetAnnealing(double alpha) {
  alpha_ = std::max(0.0, alpha);
  for (int l = 0; l < options_.num_bands; ++l) {
    const double t = std::clamp(alpha_ - l, 0.0, 1.0);
    band_weight_[l] = 0.5 * (1.0 - std::cos(M_PI * t));
  }
}

void PositionalEncoding::EncodeBatch(const Eigen::Matrix3Xd& x, Eigen::MatrixXd* out,
                                     Eigen::MatrixXd* d_out_dx) const {
  CHECK(out != nullptr);
  const int n = static_cast<int>(x.cols());
  const int D = OutputDim();
  out->resize(D, n);
  if (d_out_dx != nullptr) d_out_dx->resize(D, 3 * n);
  ParallelFor(n, [&](int begin, int end) {
    if (d_out_dx != nullptr) d_out_dx->middleCols(3 * begin, 3 * (end - begin)).setZero();
    for (int j = begin; j < end; ++j) {
      double* o = out->col(j).data();
      int r = 0;
      if (options_.include_input) {
        for (int c = 0; c < 3; ++c) {
          o[r + c] = x(c, j);
          if (d_out_dx != nullptr) (*d_out_dx)(r + c, 3 * j + c) = 1.0;
        }
        r += 3;
      }
      for (int l = 0; l < options_.num_bands; ++l) {
        const double f = band_frequency_[l];
        const double w = band_weight_[l];
        for (int c = 0; c < 3; ++c) {
          const double s = std::sin(f * x(c, j));
          const double co = std::cos(f * x(c, j));
          o[r + c] = w * s;
          o[r + 3 + c] = w * co;
          if (d_out_dx != nullptr) {
            (*d_out_dx)(r + c, 3 * j + c) = w * f * co;
            (*d_out_dx)(r + 3 + c, 3 * j + c) = -w * f * s;
          }
        }
        r += 6;
      }
    }
  });
}

void PositionalEncoding::EncodeSecondDerivativeBatch(const Eigen::Matrix3Xd& x,
                                                     Eigen::MatrixXd* d2) const {
  CHECK(d2 != nullptr);
  const int n = static_cast<int>(x.cols());
  d2->setZero(OutputDim(), n);
  for (int j = 0; j < n; ++j) {
    int r = options_.include_input ? 3 : 0;
    for (int l = 0; l < options_.num_bands; ++l) {
      const double f = band_frequency_[l];
      const double w = band_weight_[l];
      for (int c = 0; c < 3; ++c) {
        (*d2)(r + c, j) = -w * f * f * std::sin(f * x(c, j));
        (*d2)(r + 3 + c, j) = -w * f * f * std::cos(f * x(c, j));
      }
      r += 6;
    }
  }
}

}  // namespace banmo
