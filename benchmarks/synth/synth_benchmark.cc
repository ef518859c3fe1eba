// Synthetic generator micro benchmarks: skinning, rasterising, whole scenes.
#include <benchmark/benchmark.h>

#include "banmo/synth/rasterizer.h"
#include "banmo/synth/rig_library.h"
#include "banmo/synth/scene.h"

namespace banmo::synth {
namespace {

const Rig& Quadruped() {
  static const Rig rig = LoadRig("quadruped");
  return rig;
}

void BM_PoseRig_Quadruped(benchmark::State& state) {
  const Rig& rig = Quadruped();
  double t = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(PoseRig(rig, &rig.animations[0], t));
    t += 0.01;
  }
  state.SetItemsProcessed(state.iterations() * rig.NumVertices());
}
BENCHMARK(BM_PoseRig_Quadruped)->Unit(benchmark::kMillisecond);

void BM_Rasterize_Quadruped(benchmark::State& state) {
  const Rig& rig = Quadruped();
  SynthOptions o;
  o.num_videos = 1;
  o.frames_per_video = 2;
  o.image_size = static_cast<int>(state.range(0));
  const ScenePlan plan = PlanScene(rig, o);
  const Eigen::Matrix3Xd vertices =
      IsometryFromPose(plan.frames[0][0].camera_from_root_gt.data()) *
      PosedVerticesInRoot(rig, plan, plan.frames[0][0].animation_time);
  for (auto _ : state) benchmark::DoNotOptimize(Rasterize(plan.camera, vertices, rig.faces));
}
BENCHMARK(BM_Rasterize_Quadruped)->Arg(256)->Arg(512)->Unit(benchmark::kMillisecond);

// One video of 16 frames with 4 flow gaps (both cores).
void BM_RenderScene_Quadruped(benchmark::State& state) {
  const Rig& rig = Quadruped();
  SynthOptions o;
  o.num_videos = 1;
  o.frames_per_video = 16;
  o.image_size = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(RenderSyntheticScene(rig, o));
  state.SetItemsProcessed(state.iterations() * o.frames_per_video);
}
BENCHMARK(BM_RenderScene_Quadruped)->Arg(256)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace banmo::synth

BENCHMARK_MAIN();
