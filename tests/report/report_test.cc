// The report's helpers: base64, CSV cells, HTML escaping, the SVG plots, and
// FindRunFolders' errors.
#include "banmo/report/report.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "banmo/util/error.h"

namespace banmo {
namespace {

TEST(ReportUtil, Base64MatchesRfc4648) {
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(Base64(std::string("\xff\x00\xfe", 3)), "/wD+");
}

TEST(ReportUtil, HtmlEscape) {
  EXPECT_EQ(HtmlEscape("a<b & \"c\" 'd'>"), "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;");
}

TEST(ReportUtil, ReadCsvCellsAndNumbers) {
  const std::string path = ::testing::TempDir() + "/report_test.csv";
  {
    std::ofstream out(path);
    out << "a,b,c\n1,,x\n2.5,3,\n";
  }
  const CsvTable t = ReadCsv(path);
  ASSERT_TRUE(t.exists);
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_EQ(t.Column("c"), 2);
  EXPECT_EQ(t.Column("d"), -1);
  EXPECT_EQ(t.Number(0, 0), 1.0);
  EXPECT_TRUE(std::isnan(t.Number(0, 1)));  // empty
  EXPECT_TRUE(std::isnan(t.Number(0, 2)));  // not a number
  EXPECT_EQ(t.Number(1, 1), 3.0);
  EXPECT_TRUE(std::isnan(t.Number(1, 2)));  // trailing empty cell
  EXPECT_TRUE(std::isnan(t.Number(5, 0)));  // no such row
  EXPECT_FALSE(ReadCsv(path + ".missing").exists);
}

TEST(ReportUtil, LinePlotSvgBreaksAtNanAndDropsNonPositiveOnLogScale) {
  PlotSeries s;
  s.name = "rgb <loss>";
  s.x = {0, 1, 2, 3, 4};
  s.y = {1.0, 0.5, std::numeric_limits<double>::quiet_NaN(), 0.1, -1.0};
  PlotOptions o;
  o.title = "t";
  o.log_y = true;
  const std::string svg = LinePlotSvg({s}, o);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_NE(svg.find("rgb &lt;loss&gt;"), std::string::npos);  // escaped legend
  // Two pieces: points 0-1, then point 3 alone (2 is NaN, 4 is negative).
  const size_t d = svg.find("<path d=\"");
  ASSERT_NE(d, std::string::npos);
  const std::string path = svg.substr(d, svg.find('"', d + 9) - d);
  EXPECT_EQ(std::count(path.begin(), path.end(), 'M'), 2) << path;
  EXPECT_EQ(std::count(path.begin(), path.end(), 'L'), 1) << path;
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  // Values far below the largest sit on the bottom edge of a log plot (8
  // decades; the plot area ends at y = height - 40 = 240).
  PlotSeries tiny;
  tiny.name = "tiny";
  tiny.x = {0, 1};
  tiny.y = {1.0, 1e-30};
  const std::string clamped = LinePlotSvg({tiny}, o);
  EXPECT_NE(clamped.find("L490.0,240.0\""), std::string::npos) << clamped;
  // No finite data: says so.
  PlotSeries empty;
  empty.x = {0};
  empty.y = {std::numeric_limits<double>::quiet_NaN()};
  EXPECT_NE(LinePlotSvg({empty}, o).find("no data"), std::string::npos);
}

TEST(ReportUtil, FindRunFoldersNamesWhatIsMissing) {
  const std::string dir = ::testing::TempDir() + "/report_test_run";
  std::filesystem::remove_all(dir);
  try {
    FindRunFolders(dir, "");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a folder"), std::string::npos) << e.what();
  }
  std::filesystem::create_directories(dir + "/solve/checkpoint");
  try {
    FindRunFolders(dir, "");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("solve/checkpoint/model.yaml"), std::string::npos)
        << e.what();
  }
  std::ofstream(dir + "/solve/checkpoint/model.yaml") << "x\n";
  RunFolders f = FindRunFolders(dir, "");
  EXPECT_EQ(f.solve, dir + "/solve");
  EXPECT_EQ(f.data, "");
  std::filesystem::create_directories(dir + "/data");
  std::ofstream(dir + "/data/manifest.yaml") << "x\n";
  f = FindRunFolders(dir, "");
  EXPECT_EQ(f.data, std::filesystem::path(dir + "/data").lexically_normal().string());
  EXPECT_THROW(FindRunFolders(dir, dir + "/nodata"), InputError);
  ReportOptions o;
  o.frames_per_video = -1;
  EXPECT_THROW(o.Check(), InputError);
}

}  // namespace
}  // namespace banmo
