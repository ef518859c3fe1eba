#include "banmo/field/mlp_widen.h"

#include "banmo/util/logging.h"

namespace banmo {

MlpWidening WidenMlp(const Mlp& mlp, const double* params, int new_width, double incoming_noise,
                     std::mt19937* rng) {
  const MlpOptions& old_options = mlp.options();
  const int width = old_options.width;
  CHECK_GE(new_width, width);
  CHECK_GE(incoming_noise, 0.0);
  MlpWidening out;
  out.options = old_options;
  const int hidden = old_options.hidden_layers;
  if (hidden > 0) out.options.width = new_width;
  const Mlp wide(out.options);
  out.params.assign(wide.NumParameters(), 0.0);
  out.source.assign(wide.NumParameters(), -1);
  out.gradient_scale.assign(wide.NumParameters(), 1.0);

  // g_l and the replica counts c_l of every hidden layer (raw mt19937
  // output: portable across standard libraries).
  auto unit = [&] { return (static_cast<double>((*rng)()) + 0.5) / 4294967296.0; };  // (0, 1)
  out.unit_source.resize(hidden);
  std::vector<std::vector<int>> count(hidden, std::vector<int>(width, 1));
  for (int l = 0; l < hidden; ++l) {
    std::vector<int>& g = out.unit_source[l];
    g.resize(new_width);
    for (int j = 0; j < new_width; ++j) {
      g[j] = j < width ? j : static_cast<int>((*rng)() % static_cast<uint32_t>(width));
      if (j >= width) ++count[l][g[j]];
    }
  }

  for (int l = 0; l < wide.NumLinearLayers(); ++l) {
    const int in_old = mlp.LayerInputDim(l), out_new = wide.LayerOutputDim(l);
    const int in_new = wide.LayerInputDim(l);
    const bool hidden_rows = l < hidden;  // rows are units of hidden layer l
    const bool hidden_cols = l > 0;       // columns are units of hidden layer l-1
    for (int j = 0; j < out_new; ++j) {
      const int row = hidden_rows ? out.unit_source[l][j] : j;
      const double scale = hidden_rows ? 1.0 / count[l][row] : 1.0;
      const bool noisy = hidden_rows && j >= width && incoming_noise > 0;
      for (int i = 0; i < in_new; ++i) {
        const int col = hidden_cols ? out.unit_source[l - 1][i] : i;
        const double split = hidden_cols ? 1.0 / count[l - 1][col] : 1.0;
        const int from = mlp.WeightOffset(l) + row * in_old + col;
        const int to = wide.WeightOffset(l) + j * in_new + i;
        double w = params[from] * split;
        if (noisy) w *= 1.0 + incoming_noise * (2.0 * unit() - 1.0);
        out.params[to] = w;
        out.source[to] = from;
        out.gradient_scale[to] = scale;
      }
      const int from = mlp.BiasOffset(l) + row;
      const int to = wide.BiasOffset(l) + j;
      double b = params[from];
      if (noisy) b *= 1.0 + incoming_noise * (2.0 * unit() - 1.0);
      out.params[to] = b;
      out.source[to] = from;
      out.gradient_scale[to] = scale;
    }
  }
  return out;
}

}  // namespace banmo
