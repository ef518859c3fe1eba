// Fourier-feature positional encoding (NeRF, Mildenhall et al. 2020, Eq. 4)
// with optional BARF-style coarse-to-fine annealing (Lin et al. 2021, Eq. 14),
// as used by BANMo (Yang et al. 2022, Sec. 3.1) for the canonical fields.
//
// Output layout for an input x = (x0, x1, x2), OutputDim() values:
//   [x0, x1, x2]                                   if include_input
//   then for each band l = 0 .. num_bands-1:
//   [w_l sin(f_l x0), w_l sin(f_l x1), w_l sin(f_l x2),
//    w_l cos(f_l x0), w_l cos(f_l x1), w_l cos(f_l x2)]
// with the angular frequency f_l = 2^l * pi * base_frequency (radians per unit
// of x; band l has period 2 / (2^l base_frequency) units, so with the default
// base_frequency = 1 band 0 spans the canonical cube [-1, 1] once) and the
// annealing window w_l (1 when annealing is off, see SetAnnealing).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <string>
#include <vector>

namespace banmo {

struct PositionalEncodingOptions {
  // Number of frequency bands L (>= 0). 0 with include_input = true is the
  // identity map.
  int num_bands = 6;
  // Whether the raw input is the first 3 outputs.
  bool include_input = true;
  // Scale of all frequencies (> 0): band l uses angular frequency
  // 2^l * pi * base_frequency radians per unit, i.e. 2^(l-1) * base_frequency
  // cycles per unit.
  double base_frequency = 1.0;

  // Throws InputError naming the field under `key` ("<key>.num_bands must
  // be ...") unless the options are valid (num_bands in [0, 32],
  // base_frequency > 0, OutputDim() > 0).
  void Check(const std::string& key = "position_encoding") const;
};

class PositionalEncoding {
 public:
  static constexpr int kInputDim = 3;

  explicit PositionalEncoding(const PositionalEncodingOptions& options = {});

  const PositionalEncodingOptions& options() const { return options_; }

  // 3 * (include_input + 2 * num_bands).
  int OutputDim() const { return 3 * ((options_.include_input ? 1 : 0) + 2 * options_.num_bands); }

  // Coarse-to-fine window (BARF): band l gets weight
  //   w_l = (1 - cos(pi * clamp(alpha - l, 0, 1))) / 2,
  // so alpha = 0 switches all bands off, alpha >= num_bands switches all on.
  // The default (no call) is all bands on. alpha < 0 is treated as 0.
  void SetAnnealing(double alpha);
  double annealing_alpha() const { return alpha_; }
  // Weight of band l (1 when annealing is off or finished).
  double BandWeight(int l) const { return band_weight_[l]; }
  // Angular frequency of band l: 2^l * pi * base_frequency.
  double BandFrequency(int l) const { return band_frequency_[l]; }

  // Single point, any scalar type (double or ceres::Jet): out has OutputDim()
  // entries.
  template <typename T>
  void Encode(const T* x, T* out) const;

  // Batched, column per sample. out: OutputDim x n. d_out_dx (may be null):
  // OutputDim x 3n, block j (columns 3j..3j+2) = d out_j / d x_j (each row has
  // one non-zero, the block is stored dense).
  void EncodeBatch(const Eigen::Matrix3Xd& x, Eigen::MatrixXd* out,
                   Eigen::MatrixXd* d_out_dx) const;

  // Second derivatives, batched: d2 (OutputDim x n), d2(r, j) =
  // d^2 out_j[r] / d x_j[c(r)]^2 where c(r) is the one coordinate output r
  // depends on (InputCoordinate(r)). Used by the eikonal's position gradient.
  void EncodeSecondDerivativeBatch(const Eigen::Matrix3Xd& x, Eigen::MatrixXd* d2) const;

  // The input coordinate (0, 1, 2) that output r depends on.
  int InputCoordinate(int r) const { return r % 3; }

 private:
  PositionalEncodingOptions options_;
  double alpha_ = -1.0;  // < 0: annealing off
  std::vector<double> band_weight_;
  std::vector<double> band_frequency_;
};

template <typename T>
void PositionalEncoding::Encode(const T* x, T* out) const {
  using std::cos;
  using std::sin;
  int r = 0;
  if (options_.include_input) {
    for (int c = 0; c < 3; ++c) out[r++] = x[c];
  }
  for (int l = 0; l < options_.num_bands; ++l) {
    const double f = band_frequency_[l];
    const double w = band_weight_[l];
    for (int c = 0; c < 3; ++c) out[r + c] = w * sin(f * x[c]);
    for (int c = 0; c < 3; ++c) out[r + 3 + c] = w * cos(f * x[c]);
    r += 6;
  }
}

}  // namespace banmo
