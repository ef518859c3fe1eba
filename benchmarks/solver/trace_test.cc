// The trace harness's config overrides, finiteness check and CSV rows.
#include "trace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>

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
    batches: 10
  - name: b
    batches: 20
    step_rule: lm
)";

TEST(ConfigOverrides, SetsScalarsListsAndEveryStage) {
  const SolverConfig c = ParseConfigWithOverrides(
      kBase,
      {"model.num_bones=16", "stages[*].step_rule=alternate", "stages[*].pose_solve.every=4",
       "stages[1].batches=5", "stages[*].sampling.flow_gaps=[8]",
       "stages[*].lm.linear_solver=iterative_schur", "model.field.sdf_width=24",
       "defaults.samples_per_ray=12"},
      "base.yaml");
  EXPECT_EQ(c.model.num_bones, 16);
  EXPECT_EQ(c.model.field.sdf_width, 24);
  ASSERT_EQ(c.stages.size(), 2u);
  for (const StageConfig& s : c.stages) {
    EXPECT_EQ(s.step_rule, StepRule::kAlternate);
    EXPECT_EQ(s.sampling.flow_gaps, std::vector<int>{8});
    EXPECT_EQ(s.lm.linear_solver, LinearSolverType::kIterativeSchur);
    EXPECT_EQ(s.batch_rays, 128);      // untouched defaults: still merged
    EXPECT_EQ(s.samples_per_ray, 12);  // from the overridden defaults
  }
  EXPECT_EQ(c.stages[0].batches, 10);
  EXPECT_EQ(c.stages[1].batches, 5);
}

TEST(ConfigOverrides, NoOverridesIsTheConfigItself) {
  const SolverConfig a = ParseSolverConfig(kBase, "x");
  const SolverConfig b = ParseConfigWithOverrides(kBase, {}, "x");
  EXPECT_EQ(SolverConfigToYaml(a), SolverConfigToYaml(b));
}

TEST(ConfigOverrides, BadOverridesAreInputErrors) {
  auto parse = [](const std::string& o) { ParseConfigWithOverrides(kBase, {o}, "base.yaml"); };
  EXPECT_THROW(parse("model.num_bones"), InputError);      // no '='
  EXPECT_THROW(parse("stages[2].batches=3"), InputError);  // out of range
  EXPECT_THROW(parse("model[0].x=3"), InputError);         // not a list
  EXPECT_THROW(parse("stages[x].batches=3"), InputError);  // bad index
  EXPECT_THROW(parse("model.num_bonez=3"), InputError);    // unknown key (config parser)
  EXPECT_THROW(parse("model.num_bones=abc"), InputError);  // wrong type (config parser)
  EXPECT_THROW(parse("model.num_bones.x=3"), InputError);  // below a scalar
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

// The harness's tables (configs.txt, stability.txt, scenes.txt): every named
// configuration and stability case applies to its mode's base config (as
// run.sh passes it: full = problems/default.yaml, quick = problems/tiny.yaml,
// each with its budget of budgets.txt), names are unique per mode and every stability
// scene exists. A typo would otherwise surface only when run.sh reaches it,
// an hour into a full run.
struct TableLine {
  std::string modes;
  std::vector<std::string> columns;  // the rest of the line, split on blanks
  int line = 0;
};

std::vector<TableLine> ReadTable(const std::string& name) {
  const std::string path = std::string(BANMO_SOURCE_DIR) + "/benchmarks/solver/" + name;
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<TableLine> out;
  int number = 0;
  for (std::string text; std::getline(in, text);) {
    ++number;
    std::istringstream words(text);
    TableLine line;
    line.line = number;
    if (!(words >> line.modes) || line.modes[0] == '#') continue;
    for (std::string w; words >> w;) line.columns.push_back(w);
    out.push_back(line);
  }
  return out;
}

bool InMode(const std::string& modes, const std::string& mode) {
  return modes == "all" || modes == mode;
}

std::string ReadBase(const std::string& mode) {
  const std::string path = std::string(BANMO_SOURCE_DIR) + "/problems/" +
                           (mode == "full" ? "default.yaml" : "tiny.yaml");
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// run.sh's budget for the mode (budgets.txt): its --set overrides, which go
// before the configuration's own. Its other options (the time cap) are
// banmo_trace's, not the config's.
std::vector<std::string> BudgetOverrides(const std::string& mode) {
  std::vector<std::string> overrides;
  int lines = 0;
  for (const TableLine& l : ReadTable("budgets.txt")) {
    if (l.modes != mode) continue;
    ++lines;
    for (size_t i = 0; i < l.columns.size(); ++i) {
      if (l.columns[i] == "--set") {
        EXPECT_LT(i + 1, l.columns.size()) << "budgets.txt:" << l.line << ": --set without a value";
        if (i + 1 < l.columns.size()) overrides.push_back(l.columns[++i]);
      } else if (l.columns[i] == "--max-solve-seconds") {
        EXPECT_LT(i + 1, l.columns.size()) << "budgets.txt:" << l.line;
        ++i;
      } else {
        ADD_FAILURE() << "budgets.txt:" << l.line << ": unexpected option " << l.columns[i];
      }
    }
  }
  EXPECT_EQ(lines, 1) << "budgets.txt: expected one line for mode " << mode;
  return overrides;
}

TEST(HarnessTables, EveryConfigurationParsesOnItsBase) {
  for (const std::string mode : {"full", "quick"}) {
    const std::string base = ReadBase(mode);
    ASSERT_FALSE(base.empty()) << mode;
    std::set<std::string> names;
    int count = 0;
    for (const TableLine& l : ReadTable("configs.txt")) {
      if (!InMode(l.modes, mode)) continue;
      ASSERT_GE(l.columns.size(), 2u) << "configs.txt:" << l.line << ": expected axes and name";
      const std::string& name = l.columns[1];
      EXPECT_TRUE(names.insert(name).second)
          << "configs.txt:" << l.line << ": " << name << " twice in mode " << mode;
      std::vector<std::string> overrides = BudgetOverrides(mode);
      overrides.insert(overrides.end(), l.columns.begin() + 2, l.columns.end());
      EXPECT_NO_THROW(ParseConfigWithOverrides(base, overrides, "configs.txt " + name))
          << "configs.txt:" << l.line << " (" << mode << ")";
      ++count;
    }
    EXPECT_GE(count, 10) << mode;
    EXPECT_TRUE(names.count("adam")) << "the reference configuration, mode " << mode;
  }
}

TEST(HarnessTables, EveryStabilityCaseParsesAndHasItsScene) {
  for (const std::string mode : {"full", "quick"}) {
    const std::string base = ReadBase(mode);
    std::set<std::string> scenes;
    for (const TableLine& l : ReadTable("scenes.txt")) {
      if (InMode(l.modes, mode) && !l.columns.empty()) scenes.insert(l.columns[0]);
    }
    std::set<std::string> names;
    for (const TableLine& l : ReadTable("stability.txt")) {
      if (!InMode(l.modes, mode)) continue;
      ASSERT_GE(l.columns.size(), 2u) << "stability.txt:" << l.line << ": expected name and scene";
      EXPECT_TRUE(names.insert(l.columns[0]).second) << "stability.txt:" << l.line;
      EXPECT_TRUE(scenes.count(l.columns[1]))
          << "stability.txt:" << l.line << ": scene " << l.columns[1] << " not in scenes.txt ("
          << mode << ")";
      std::vector<std::string> overrides = BudgetOverrides(mode);
      overrides.insert(overrides.end(), l.columns.begin() + 2, l.columns.end());
      EXPECT_NO_THROW(ParseConfigWithOverrides(base, overrides, "stability.txt"))
          << "stability.txt:" << l.line << " (" << mode << ")";
    }
    // The issue's hard cases, each in every mode (a mode may add variants,
    // e.g. the fixed-scale twins of the scale cases in full mode); names are
    // unique, so this also means at least 15 runs. Root-pose noise in both
    // models of `banmo synth` (exact: noiseDEG, gaussian: gnoiseDEG).
    for (const char* required :
         {"noise20", "noise50", "noise90", "gnoise20", "gnoise50", "gnoise90", "bird", "hand",
          "gap8", "scale0.01", "scale100", "bones1", "bones64", "beta1e-4", "beta10"}) {
      EXPECT_TRUE(names.count(required))
          << "stability.txt has no " << required << " (" << mode << ")";
    }
  }
}

}  // namespace
}  // namespace banmo::bench
