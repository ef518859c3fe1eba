// The solver's state beyond the model's parameters: everything a resumed
// run needs to continue bit-identically (checkpoint state.bin).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "banmo/optim/ray_sampler.h"

namespace banmo {

struct SolverState {
  int stage = 0;
  int batch = 0;  // batches done in the stage
  int total_batches = 0;
  std::mt19937 rng;
  double lm_radius = -1.0;  // < 0: the stage's initial radius
  struct Moments {
    std::vector<double> m, v;
    int64_t steps = 0;
  };
  std::map<std::string, Moments> adam;  // by block name (Model::ForEachBlock)
  std::vector<RaySampler::CachedPixel> error_cache;
  Eigen::AlignedBox3d bounds;

  // Forgets the Adam moments of every block whose name contains `part`
  // (blocks whose parameters jumped: a solve or a registration moved them).
  void DropAdamMoments(const std::string& part);

  // state.bin: "BANMOST1", then the fields above in order.
  std::string Serialize() const;
  // Throws InputError on a truncated or foreign file.
  void Deserialize(const std::string& in);
};

}  // namespace banmo
