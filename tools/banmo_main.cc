// banmo: animatable 3D models from casual videos (BANMo) with Ceres Solver.
// Dispatches to the subcommands registered in tools/cmd_*.cc.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "banmo/util/error.h"
#include "banmo/util/logging.h"
#include "command.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace {

void PrintUsage() {
  std::printf(
      "banmo: build animatable 3D models of deformable objects from several videos\n"
      "(BANMo, solved as one nonlinear least-squares problem with Ceres).\n\n"
      "Usage: banmo <command> [options]\n       banmo <command> --help\n\nCommands:\n");
  for (const auto& [name, command] : banmo::tools::CommandRegistry()) {
    std::printf("  %-10s %s\n", name.c_str(), command.summary.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // glibc serves blocks over its mmap threshold (128 kB at start) by mmap
  // and hands them back on free (its dynamic threshold did not prevent it
  // here), so code that builds its per-chunk matrices afresh (the MLP
  // caches of a ray batch: MBs each) takes a page fault per 4 kB page on
  // every call: `banmo render` spent about 40 % of its CPU time in the
  // kernel and ran 2.7x slower (docs/render.md, "Measured"). Blocks up to
  // 32 MB (the dynamic threshold's own maximum) come from the heap, and its
  // top is kept up to 256 MB instead of being trimmed.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
#endif
  banmo::InitLogging(argv[0]);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0 ||
      std::strcmp(argv[1], "help") == 0) {
    PrintUsage();
    return argc < 2 ? 1 : 0;
  }
  const auto& registry = banmo::tools::CommandRegistry();
  const auto it = registry.find(argv[1]);
  if (it == registry.end()) {
    std::fprintf(stderr, "banmo: unknown command '%s'\n\n", argv[1]);
    PrintUsage();
    return 1;
  }
  // The subcommand sees argv[0] = "banmo <name>" and its own options.
  std::string name = std::string("banmo ") + argv[1];
  std::vector<char*> sub_argv;
  sub_argv.push_back(name.data());
  for (int i = 2; i < argc; ++i) sub_argv.push_back(argv[i]);
  try {
    return it->second.run(static_cast<int>(sub_argv.size()), sub_argv.data());
  } catch (const banmo::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "internal error: %s\n", e.what());
    return 3;
  }
}
