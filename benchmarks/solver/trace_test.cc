// The trace harness's config overrides, finiteness check and CSV rows.
#include "trace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "banmo/optim/solver.h"
#include "banmo/util/error.h"

namespace banmo::bench {
namespace {

const char* kBase = R"(
model:
  num_bones: 8
defaults:
  batch_rays: 128
stages:
  - name: a
    iterations: 10
  - name: b
    iterations: 20
    step_rule: lm
)";

TEST(ConfigOverrides, SetsScalarsListsAndEveryStage) {
  const SolverConfig c = ParseConfigWithOverrides(
      kBase,
      {"model.num_bones=16", "stages[*].step_rule=alternate", "stages[1].iterations=5",
       "stages[*].sampling.flow_gaps=[8]", "stages[*].lm.linear_solver=iterative_schur",
       "model.field.sdf_width=24", "defaults.samples_per_ray=12"},
      "base.yaml");
  EXPECT_EQ(c.model.num_bones, 16);
  EXPECT_EQ(c.model.field.sdf_width, 24);
  ASSERT_EQ(c.stages.size(), 2u);
  for (const StageConfig& s : c.stages) {
    EXPECT_EQ(s.step_rule, "alternate");
    EXPECT_EQ(s.sampling.flow_gaps, std::vector<int>{8});
    EXPECT_EQ(s.lm.linear_solver, "iterative_schur");
    EXPECT_EQ(s.batch_rays, 128);      // untouched defaults: still merged
    EXPECT_EQ(s.samples_per_ray, 12);  // from the overridden defaults
  }
  EXPECT_EQ(c.stages[0].iterations, 10);
  EXPECT_EQ(c.stages[1].iterations, 5);
}

TEST(ConfigOverrides, NoOverridesIsTheConfigItself) {
  const SolverConfig a = ParseSolverConfig(kBase, "x");
  const SolverConfig b = ParseConfigWithOverrides(kBase, {}, "x");
  EXPECT_EQ(SolverConfigToYaml(a), SolverConfigToYaml(b));
}

TEST(ConfigOverrides, BadOverridesAreInputErrors) {
  auto parse = [](const std::string& o) { ParseConfigWithOverrides(kBase, {o}, "base.yaml"); };
  EXPECT_THROW(parse("model.num_bones"), InputError);         // no '='
  EXPECT_THROW(parse("stages[2].iterations=3"), InputError);  // out of range
  EXPECT_THROW(parse("model[0].x=3"), InputError);            // not a list
  EXPECT_THROW(parse("stages[x].iterations=3"), InputError);  // bad index
  EXPECT_THROW(parse("model.num_bonez=3"), InputError);       // unknown key (config parser)
  EXPECT_THROW(parse("model.num_bones=abc"), InputError);     // wrong type (config parser)
  EXPECT_THROW(parse("model.num_bones.x=3"), InputError);     // below a scalar
  try {
    parse("model.num_bonez=3");
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("num_bonez"), std::string::npos) << e.what();
  }
}

TEST(FirstNonFiniteBlock, NamesTheBlock) {
  ModelOptions options;
  options.num_bones = 2;
  options.field.sdf_width = 8;
  options.field.color_width = 8;
  options.field.embedding_width = 8;
  Model model(options, {2, 3}, {PinholeCamera(), PinholeCamera()});
  EXPECT_EQ(FirstNonFiniteBlock(model), "");
  model.frame(1, 2).bones_t[3] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(FirstNonFiniteBlock(model), "video1/frame2/bones_t");
  model.sdf()[0] = std::nan("");
  EXPECT_EQ(FirstNonFiniteBlock(model), "sdf");
}

TEST(TraceCsv, RowHasOneFieldPerHeaderColumn) {
  TraceRow row;
  row.config = "adam";
  row.scene = "q";
  row.kind = "trace";
  row.losses = {{"rgb", 0.5}, {"flow", 0.25}};
  row.chamfer_cm = std::nan("");
  const std::string header = TraceCsvHeader(), line = TraceCsvLine(row);
  auto count = [](const std::string& s) { return std::count(s.begin(), s.end(), ','); };
  EXPECT_EQ(count(header), count(line));
  EXPECT_NE(line.find(",0.75,"), std::string::npos) << line;  // loss_total
  EXPECT_NE(line.find(",nan,"), std::string::npos) << line;
}

}  // namespace
}  // namespace banmo::bench
