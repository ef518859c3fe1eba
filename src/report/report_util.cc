// CSV reading, HTML escaping, base64 and the SVG line plots of the report.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

#include "banmo/report/report.h"

namespace banmo {

int CsvTable::Column(const std::string& name) const {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name) return static_cast<int>(i);
  }
  return -1;
}

double CsvTable::Number(size_t row, int column) const {
  if (row >= rows.size() || column < 0 || static_cast<size_t>(column) >= rows[row].size()) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const std::string& cell = rows[row][column];
  if (cell.empty()) return std::numeric_limits<double>::quiet_NaN();
  char* end = nullptr;
  const double value = std::strtod(cell.c_str(), &end);
  if (end == cell.c_str() || *end != '\0') return std::numeric_limits<double>::quiet_NaN();
  return value;
}

namespace {

std::vector<std::string> SplitLine(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::stringstream ss(line);
  while (std::getline(ss, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

}  // namespace

CsvTable ReadCsv(const std::string& path) {
  CsvTable table;
  std::ifstream in(path);
  if (!in) return table;
  table.exists = true;
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (first) {
      table.header = SplitLine(line);
      first = false;
    } else {
      table.rows.push_back(SplitLine(line));
    }
  }
  return table;
}

std::string HtmlEscape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char kTable[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                       (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += kTable[(v >> 6) & 63];
    out += kTable[v & 63];
  }
  if (i < bytes.size()) {
    unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<unsigned char>(bytes[i + 1]) << 8;
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kTable[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

namespace {

// Series colours (the bone palette's first entries, readable on white).
const char* SeriesColor(size_t i) {
  static const char* kColors[] = {"#e6194b", "#3cb44b", "#0082c8", "#f58230", "#911eb4", "#008080",
                                  "#f032e6", "#aa6e28", "#800000", "#808000", "#000080", "#808080"};
  return kColors[i % (sizeof(kColors) / sizeof(kColors[0]))];
}

std::string Fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f", v);
  return buf;
}

// A tick label: short, readable number.
std::string TickLabel(double v) {
  char buf[32];
  const double a = std::abs(v);
  if (a != 0 && (a < 1e-3 || a >= 1e5)) {
    std::snprintf(buf, sizeof(buf), "%.0e", v);
  } else {
    std::snprintf(buf, sizeof(buf), "%g", std::round(v * 1e4) / 1e4);
  }
  return buf;
}

// About `count` round tick values covering [lo, hi].
std::vector<double> Ticks(double lo, double hi, int count) {
  std::vector<double> ticks;
  const double span = hi - lo;
  if (!(span > 0)) return {lo};
  const double raw = span / count;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  }
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * span; t += step) {
    ticks.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  }
  return ticks;
}

}  // namespace

std::string LinePlotSvg(const std::vector<PlotSeries>& series, const PlotOptions& options) {
  const double left = 62, right = 150, top = 24, bottom = 40;
  const double w = options.width, h = options.height;
  const double pw = w - left - right, ph = h - top - bottom;
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin, ymin = xmin, ymax = -xmin;
  auto y_of = [&](double y) {
    if (!std::isfinite(y)) return std::numeric_limits<double>::quiet_NaN();
    if (options.log_y) return y > 0 ? std::log10(y) : std::numeric_limits<double>::quiet_NaN();
    return y;
  };
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      const double y = y_of(s.y[i]);
      if (!std::isfinite(s.x[i]) || !std::isfinite(y)) continue;
      xmin = std::min(xmin, s.x[i]);
      xmax = std::max(xmax, s.x[i]);
      ymin = std::min(ymin, y);
      ymax = std::max(ymax, y);
    }
  }
  std::ostringstream svg;
  svg << "<svg class=\"plot\" width=\"" << w << "\" height=\"" << h << "\" viewBox=\"0 0 " << w
      << ' ' << h << "\">\n";
  svg << "<text x=\"" << left << "\" y=\"15\" class=\"title\">" << HtmlEscape(options.title)
      << "</text>\n";
  if (!std::isfinite(xmin)) {
    svg << "<text x=\"" << left << "\" y=\"" << top + ph / 2 << "\">no data</text>\n</svg>\n";
    return svg.str();
  }
  if (xmax == xmin) {
    xmin -= 0.5;
    xmax += 0.5;
  } else {
    bool points = false;
    for (const PlotSeries& s : series) points = points || s.points;
    if (points) {  // markers clear of the frame
      const double pad = 0.04 * (xmax - xmin);
      xmin -= pad;
      xmax += pad;
    }
  }
  // A log scale shows at most 8 decades below the largest value; smaller
  // values sit on the bottom edge.
  if (options.log_y && ymax - ymin > 8) ymin = ymax - 8;
  if (ymax == ymin) {
    ymin -= options.log_y ? 0.5 : std::max(0.5, std::abs(ymin) * 0.1);
    ymax += options.log_y ? 0.5 : std::max(0.5, std::abs(ymax) * 0.1);
  } else {
    const double pad = 0.04 * (ymax - ymin);
    ymin -= pad;
    ymax += pad;
  }
  auto px = [&](double x) { return left + (x - xmin) / (xmax - xmin) * pw; };
  auto py = [&](double y) { return top + (1 - (y - ymin) / (ymax - ymin)) * ph; };
  svg << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << pw << "\" height=\"" << ph
      << "\" class=\"frame\"/>\n";
  for (const double t : Ticks(ymin, ymax, 5)) {
    svg << "<line x1=\"" << left << "\" x2=\"" << Fmt(left + pw) << "\" y1=\"" << Fmt(py(t))
        << "\" y2=\"" << Fmt(py(t)) << "\" class=\"grid\"/>";
    svg << "<text x=\"" << left - 4 << "\" y=\"" << Fmt(py(t) + 4) << "\" class=\"ytick\">"
        << TickLabel(options.log_y ? std::pow(10.0, t) : t) << "</text>\n";
  }
  for (const double t : Ticks(xmin, xmax, 6)) {
    svg << "<text x=\"" << Fmt(px(t)) << "\" y=\"" << Fmt(top + ph + 14) << "\" class=\"xtick\">"
        << TickLabel(t) << "</text>\n";
  }
  svg << "<text x=\"" << Fmt(left + pw / 2) << "\" y=\"" << h - 6 << "\" class=\"xlabel\">"
      << HtmlEscape(options.x_label) << "</text>\n";
  svg << "<text x=\"12\" y=\"" << Fmt(top + ph / 2)
      << "\" class=\"ylabel\" transform=\"rotate(-90 12 " << Fmt(top + ph / 2) << ")\">"
      << HtmlEscape(options.y_label) << (options.log_y ? " (log)" : "") << "</text>\n";
  for (size_t k = 0; k < series.size(); ++k) {
    const PlotSeries& s = series[k];
    const char* color = SeriesColor(k);
    std::string path;
    bool pen_down = false;
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      double y = y_of(s.y[i]);
      if (!std::isfinite(s.x[i]) || !std::isfinite(y)) {
        pen_down = false;
        continue;
      }
      y = std::max(y, ymin);
      if (s.points) {
        svg << "<circle cx=\"" << Fmt(px(s.x[i])) << "\" cy=\"" << Fmt(py(y))
            << "\" r=\"3\" fill=\"" << color << "\"/>";
        continue;
      }
      path += (pen_down ? " L" : " M") + Fmt(px(s.x[i])) + "," + Fmt(py(y));
      pen_down = true;
    }
    if (!path.empty()) {
      svg << "<path d=\"" << path << "\" fill=\"none\" stroke=\"" << color
          << "\" stroke-width=\"1.5\"/>\n";
    }
    const double ly = top + 10 + 16 * static_cast<double>(k);
    svg << "<line x1=\"" << Fmt(left + pw + 10) << "\" x2=\"" << Fmt(left + pw + 28) << "\" y1=\""
        << Fmt(ly - 4) << "\" y2=\"" << Fmt(ly - 4) << "\" stroke=\"" << color
        << "\" stroke-width=\"3\"/><text x=\"" << Fmt(left + pw + 32) << "\" y=\"" << Fmt(ly)
        << "\" class=\"legend\">" << HtmlEscape(s.name) << "</text>\n";
  }
  svg << "</svg>\n";
  return svg.str();
}

}  // namespace banmo
