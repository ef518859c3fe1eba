// The solver's checkpoint state (optim/solver_state.cc, state.bin).
#include "fuzz_util.h"
#include "solver_state.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes = banmo::fuzz::AsString(data, size);
  banmo::fuzz::Expect([&] {
    banmo::SolverState state;
    state.Deserialize(bytes);
  });
  return 0;
}
