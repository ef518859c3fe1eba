// Micro benchmarks of the batched MLP passes at the minibatch size of the
// design (32 samples x 1024 rays = 32768 samples), SDF-shaped network:
// PE(L = 6) input (39), 3 hidden layers of width 16/32/64, output 1 + 8.
// Args: {width, threads}.
#include <benchmark/benchmark.h>
#include <ceres/jet.h>

#include <random>

#include "banmo/field/canonical_field.h"
#include "banmo/field/mlp.h"
#include "banmo/util/parallel.h"

namespace banmo {
namespace {

constexpr int kSamplesPerRay = 32;
constexpr int kRays = 1024;
constexpr int kN = kSamplesPerRay * kRays;

struct Setup {
  explicit Setup(int width) : mlp(Options(width)) {
    params.resize(mlp.NumParameters());
    mlp.InitializeDefault(1, params.data());
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    inputs.resize(mlp.InputDim(), kN);
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < mlp.InputDim(); ++i) inputs(i, j) = u(rng);
    d_out.resize(mlp.OutputDim(), kN);
    for (int j = 0; j < kN; ++j)
      for (int i = 0; i < mlp.OutputDim(); ++i) d_out(i, j) = u(rng);
    for (int g = 0; g <= kRays; ++g) groups.push_back(g * kSamplesPerRay);
    mlp.ForwardBatch(params.data(), inputs, &cache, nullptr);
  }
  static MlpOptions Options(int width) {
    MlpOptions o;
    o.input_dim = 39;
    o.output_dim = 9;
    o.width = width;
    o.hidden_layers = 3;
    return o;
  }
  Mlp mlp;
  std::vector<double> params;
  Eigen::MatrixXd inputs, d_out;
  std::vector<int> groups;
  MlpCache cache;
};

void SetThreads(benchmark::State& state) { SetNumThreads(static_cast<int>(state.range(1))); }

void BM_Mlp_ForwardBatch(benchmark::State& state) {
  SetThreads(state);
  Setup s(static_cast<int>(state.range(0)));
  Eigen::MatrixXd out;
  for (auto _ : state) {
    s.mlp.ForwardBatch(s.params.data(), s.inputs, &s.cache, &out);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["params"] = s.mlp.NumParameters();
  state.SetItemsProcessed(state.iterations() * kN);
}

// One reverse pass with per-ray (per-group) weight gradients: what the lead
// calls once per residual row.
void BM_Mlp_BackwardPerGroup(benchmark::State& state) {
  SetThreads(state);
  Setup s(static_cast<int>(state.range(0)));
  Eigen::MatrixXd d_params;
  for (auto _ : state) {
    s.mlp.Backward(s.params.data(), s.cache, s.d_out, s.groups, &d_params, nullptr);
    benchmark::DoNotOptimize(d_params.data());
  }
  state.counters["params"] = s.mlp.NumParameters();
  state.SetItemsProcessed(state.iterations() * kN);
}

// Reverse pass over the whole batch as one group (the J^T r gradient).
void BM_Mlp_BackwardOneGroup(benchmark::State& state) {
  SetThreads(state);
  Setup s(static_cast<int>(state.range(0)));
  Eigen::MatrixXd d_params;
  const std::vector<int> one = {0, kN};
  for (auto _ : state) {
    s.mlp.Backward(s.params.data(), s.cache, s.d_out, one, &d_params, nullptr);
    benchmark::DoNotOptimize(d_params.data());
  }
  state.SetItemsProcessed(state.iterations() * kN);
}

// Input Jacobians: 3 forward tangents per sample.
void BM_Mlp_ForwardTangents3(benchmark::State& state) {
  SetThreads(state);
  Setup s(static_cast<int>(state.range(0)));
  const Eigen::MatrixXd t = Eigen::MatrixXd::Random(s.mlp.InputDim(), 3 * kN);
  Eigen::MatrixXd out;
  for (auto _ : state) {
    s.mlp.ForwardTangents(s.params.data(), s.cache, t, 3, &out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * kN);
}

// Eikonal weight Jacobian (reverse of the tangent), per ray.
void BM_Mlp_BackwardOfTangentPerGroup(benchmark::State& state) {
  SetThreads(state);
  Setup s(static_cast<int>(state.range(0)));
  const Eigen::MatrixXd v = Eigen::MatrixXd::Random(s.mlp.InputDim(), kN);
  Eigen::MatrixXd d_params;
  for (auto _ : state) {
    s.mlp.BackwardOfTangent(s.params.data(), s.cache, v, s.d_out, s.groups, &d_params, nullptr,
                            nullptr);
    benchmark::DoNotOptimize(d_params.data());
  }
  state.SetItemsProcessed(state.iterations() * kN);
}

// Reference cost for comparison: ONE ray's (32 samples) weight gradient
// through the templated path with Jets over all weights (chunks of 32
// derivative slots), i.e. what pure autodiff would pay per residual row.
void BM_Mlp_FullJetOneRay(benchmark::State& state) {
  SetNumThreads(1);
  Setup s(static_cast<int>(state.range(0)));
  using J = ceres::Jet<double, 32>;
  const int P = s.mlp.NumParameters();
  std::vector<J> pj(P), xj(s.mlp.InputDim()), out(s.mlp.OutputDim());
  Eigen::VectorXd grad(P);
  for (auto _ : state) {
    for (int c0 = 0; c0 < P; c0 += 32) {
      for (int i = 0; i < P; ++i) {
        pj[i] = J(s.params[i]);
        if (i >= c0 && i < c0 + 32) pj[i].v[i - c0] = 1.0;
      }
      for (int j = 0; j < kSamplesPerRay; ++j) {
        for (int i = 0; i < s.mlp.InputDim(); ++i) xj[i] = J(s.inputs(i, j));
        s.mlp.Forward(pj.data(), xj.data(), out.data());
        for (int i = c0; i < std::min(P, c0 + 32); ++i) grad[i] = out[0].v[i - c0];
      }
    }
    benchmark::DoNotOptimize(grad.data());
  }
}

// Whole canonical field (default options) forward with all input Jacobians.
void BM_CanonicalField_ForwardBatchWithJacobians(benchmark::State& state) {
  SetNumThreads(static_cast<int>(state.range(0)));
  const CanonicalFieldOptions o;
  const CanonicalField field(o);
  std::vector<double> sdf(field.SdfParameterSize()), color(field.ColorParameterSize()),
      emb(field.EmbeddingParameterSize());
  field.InitializeParameters(1, sdf.data(), color.data(), emb.data());
  FieldBatch b;
  b.x = Eigen::Matrix3Xd::Random(3, kN);
  b.view_dir = Eigen::Matrix3Xd::Random(3, kN).colwise().normalized();
  b.appearance = Eigen::MatrixXd::Random(o.appearance_code_dim, kN);
  for (auto _ : state) {
    field.ForwardBatch(sdf.data(), color.data(), &b, true);
    benchmark::DoNotOptimize(b.rgb.data());
  }
  state.SetItemsProcessed(state.iterations() * kN);
}

#define BANMO_WIDTH_ARGS \
  ArgsProduct({{16, 32, 64}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime()

BENCHMARK(BM_Mlp_ForwardBatch)->BANMO_WIDTH_ARGS;
BENCHMARK(BM_Mlp_BackwardPerGroup)->BANMO_WIDTH_ARGS;
BENCHMARK(BM_Mlp_BackwardOneGroup)->BANMO_WIDTH_ARGS;
BENCHMARK(BM_Mlp_ForwardTangents3)->BANMO_WIDTH_ARGS;
BENCHMARK(BM_Mlp_BackwardOfTangentPerGroup)->BANMO_WIDTH_ARGS;
BENCHMARK(BM_Mlp_FullJetOneRay)->Arg(16)->Arg(32)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CanonicalField_ForwardBatchWithJacobians)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace banmo

BENCHMARK_MAIN();
