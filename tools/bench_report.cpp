// Markdown table and SVG plots of `streamcvd bench` records.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "tools/bench.h"

namespace streamcvd::cli {
namespace {

using json = nlohmann::json;

const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd",
                                "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};
constexpr size_t kPaletteSize = sizeof kPalette / sizeof kPalette[0];

std::string fmt(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, value);
  return buf;
}

std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '&') out += "&amp;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

double number(const json& j, const char* key, double fallback = NAN) {
  auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}

std::string text_at(double x, double y, const std::string& s, const char* anchor = "middle", int size = 12) {
  return "<text x=\"" + fmt("%.1f", x) + "\" y=\"" + fmt("%.1f", y) + "\" font-size=\"" + std::to_string(size) +
         "\" text-anchor=\"" + anchor + "\">" + xml_escape(s) + "</text>\n";
}

std::string line(double x0, double y0, double x1, double y1, const char* stroke, double width = 1) {
  return "<line x1=\"" + fmt("%.1f", x0) + "\" y1=\"" + fmt("%.1f", y0) + "\" x2=\"" + fmt("%.1f", x1) + "\" y2=\"" +
         fmt("%.1f", y1) + "\" stroke=\"" + stroke + "\" stroke-width=\"" + fmt("%.2g", width) + "\"/>\n";
}

std::string svg_open(int width, int height) {
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(width) + "\" height=\"" +
         std::to_string(height) + "\" viewBox=\"0 0 " + std::to_string(width) + " " + std::to_string(height) +
         "\" font-family=\"sans-serif\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
}

// A plot frame: data window [x0,x1]×[y0,y1] mapped onto the pixel box (left, top, w, h).
struct Frame {
  double left, top, w, h, x0, x1, y0, y1;
  double px(double x) const { return left + (x - x0) / (x1 - x0) * w; }
  double py(double y) const { return top + h - (y - y0) / (y1 - y0) * h; }
};

std::string frame_box(const Frame& f) {
  return "<rect x=\"" + fmt("%.1f", f.left) + "\" y=\"" + fmt("%.1f", f.top) + "\" width=\"" + fmt("%.1f", f.w) +
         "\" height=\"" + fmt("%.1f", f.h) + "\" fill=\"none\" stroke=\"black\"/>\n";
}

// One histogram panel: bars of each row's histogram (as % of its total) side by side per bin.
std::string histogram_panel(const Frame& frame_in, const json& rows, const char* key, double lo, double hi,
                            const std::string& xlabel, double tick_step) {
  std::vector<std::vector<double>> percent;
  double top = 1;
  for (const json& r : rows) {
    std::vector<double> p;
    const json& h = r["quality"][key];
    double total = 0;
    for (const json& c : h) total += c.get<double>();
    for (const json& c : h) p.push_back(total > 0 ? 100 * c.get<double>() / total : 0);
    for (double v : p) top = std::max(top, v);
    percent.push_back(std::move(p));
  }
  top = std::ceil(top / 10) * 10;
  Frame f = frame_in;
  f.x0 = lo;
  f.x1 = hi;
  f.y0 = 0;
  f.y1 = top;
  std::string s = frame_box(f);
  for (double y = 0; y <= top + 1e-9; y += top / 5) {
    s += line(f.left - 4, f.py(y), f.left, f.py(y), "black");
    s += line(f.left, f.py(y), f.left + f.w, f.py(y), "#dddddd", 0.5);
    s += text_at(f.left - 6, f.py(y) + 4, fmt("%.0f", y), "end", 11);
  }
  for (double x = lo; x <= hi + 1e-9; x += tick_step) {
    s += line(f.px(x), f.top + f.h, f.px(x), f.top + f.h + 4, "black");
    s += text_at(f.px(x), f.top + f.h + 17, fmt(tick_step < 1 ? "%.1f" : "%.0f", x), "middle", 11);
  }
  s += text_at(f.left + f.w / 2, f.top + f.h + 36, xlabel);
  s += "<text x=\"" + fmt("%.1f", f.left - 40) + "\" y=\"" + fmt("%.1f", f.top + f.h / 2) +
       "\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 " + fmt("%.1f", f.left - 40) + " " +
       fmt("%.1f", f.top + f.h / 2) + ")\">% of triangles</text>\n";
  for (size_t k = 0; k < percent.size(); ++k) {
    const size_t bins = percent[k].size();
    if (bins == 0) continue;
    const double bin_w = (hi - lo) / double(bins), bar_w = 0.8 * bin_w / double(percent.size());
    for (size_t b = 0; b < bins; ++b) {
      const double x = lo + b * bin_w + 0.1 * bin_w + k * bar_w;
      const double v = percent[k][b];
      s += "<rect x=\"" + fmt("%.2f", f.px(x)) + "\" y=\"" + fmt("%.2f", f.py(v)) + "\" width=\"" +
           fmt("%.2f", f.px(x + bar_w) - f.px(x)) + "\" height=\"" + fmt("%.2f", f.py(0) - f.py(v)) + "\" fill=\"" +
           kPalette[k % kPaletteSize] + "\"/>\n";
    }
  }
  return s;
}

}  // namespace

std::string bench_markdown(const json& records) {
  std::string s =
      "| case | algorithm | N | V out | F out | load s | algorithm s | peak MB | Qmin | Qav | % angles < 30° | "
      "Hausdorff % diag | mean dist % diag |\n"
      "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n";
  for (const json& r : records) {
    const std::string head = "| " + r.value("case", std::string("?")) + " | " + r.value("algorithm", std::string("?")) +
                             " | " + std::to_string(r.value("N", 0u)) + " | ";
    const std::string status = r.value("status", std::string("?"));
    if (status != "ok") {
      s += head + status + ": " + r.value("error", std::string()) + " | | | | | | | | | |\n";
      continue;
    }
    const json& q = r["quality"];
    const json& d = r["distance"];
    s += head + std::to_string(r["output"].value("vertices", 0ull)) + " | " +
         std::to_string(r["output"].value("faces", 0ull)) + " | " + fmt("%.2f", number(r["seconds"], "load")) + " | " +
         fmt("%.2f", number(r["seconds"], "algorithm")) + " | " +
         fmt("%.0f", number(r, "peak_rss_bytes") / 1e6) + " | " + fmt("%.3f", number(q, "q_min")) + " | " +
         fmt("%.3f", number(q, "q_avg")) + " | " + fmt("%.2f", number(q, "percent_angles_below_30")) + " | " +
         fmt("%.3f", 100 * number(d, "hausdorff_relative")) + " | " +
         fmt("%.4f", 100 * 0.5 * (number(d["a_to_b"], "mean_relative") + number(d["b_to_a"], "mean_relative"))) +
         " |\n";
  }
  return s;
}

std::string energy_svg(const json& records) {
  struct Series {
    std::string name;
    bool dashed = false;       // Lloyd
    std::vector<double> t, e;  // log10 seconds, log10 E/E_ref
  };
  // Curves of one case share their reference, the lowest final energy of its runs, so the CVD and
  // Lloyd curves of a case can be compared (paper Fig. 9). Not the lowest energy met: for IQ the
  // first CVD pass reports centroid-site energies, lower than any QEM-site energy.
  auto has_energies = [](const json& r) {
    const std::string a = r.value("algorithm", std::string());
    return r.value("status", std::string()) == "ok" && (a == "cvd" || a == "lloyd") && r.contains("energy_per_loop") &&
           r["energy_per_loop"].is_array() && !r["energy_per_loop"].empty() && r.contains("seconds_per_loop") &&
           r["seconds_per_loop"].size() == r["energy_per_loop"].size();
  };
  std::map<std::string, double> reference;
  for (const json& r : records) {
    if (!has_energies(r)) continue;
    auto it = reference.emplace(r.value("case", std::string("?")), INFINITY).first;
    const double last = r["energy_per_loop"].back().get<double>();
    if (last > 0) it->second = std::min(it->second, last);
  }
  std::vector<Series> series;
  for (const json& r : records) {
    if (!has_energies(r)) continue;
    const json& e = r["energy_per_loop"];
    const json& t = r["seconds_per_loop"];
    const std::string name = r.value("case", std::string("?"));
    const double last = reference[name];
    if (!(last > 0) || !std::isfinite(last)) continue;
    const std::string algorithm = r.value("algorithm", std::string());
    Series s{name + " " + algorithm + (r.contains("metric") ? " " + r.value("metric", std::string()) : ""),
             algorithm == "lloyd", {}, {}};
    for (size_t i = 0; i < e.size(); ++i) {
      const double ti = t[i].get<double>(), ei = e[i].get<double>() / last;
      if (ti > 0 && ei > 0) {
        s.t.push_back(std::log10(ti));
        s.e.push_back(std::log10(ei));
      }
    }
    if (!s.t.empty()) series.push_back(std::move(s));
  }
  Frame f{80, 40, 560, 340, 0, 1, 0, 1};
  double tmin = INFINITY, tmax = -INFINITY, emin = INFINITY, emax = -INFINITY;
  for (const Series& s : series) {
    for (double v : s.t) tmin = std::min(tmin, v), tmax = std::max(tmax, v);
    for (double v : s.e) emin = std::min(emin, v), emax = std::max(emax, v);
  }
  if (series.empty()) tmin = -3, tmax = 0, emin = 0, emax = 1;
  f.x0 = std::floor(tmin);
  f.x1 = std::max(std::ceil(tmax), f.x0 + 1);
  f.y0 = std::min(emin, 0.0) - 0.002;
  f.y1 = std::max(emax * 1.05, f.y0 + 0.01);
  const int width = 820, height = 440;
  std::string svg = svg_open(width, height);
  svg += text_at(f.left + f.w / 2, 22, "Clustering energy against time (CVD loops, Lloyd iterations dashed)", "middle", 14);
  svg += frame_box(f);
  for (double x = f.x0; x <= f.x1 + 1e-9; x += 1) {
    svg += line(f.px(x), f.top, f.px(x), f.top + f.h, "#dddddd", 0.5);
    svg += text_at(f.px(x), f.top + f.h + 17, fmt("%g", std::pow(10.0, x)), "middle", 11);
  }
  svg += text_at(f.left + f.w / 2, f.top + f.h + 38, "time since the first loop started (s, log scale)");
  const double ratios[] = {0.5, 0.8, 0.9, 0.95, 0.98, 0.99, 1, 1.01, 1.02, 1.05, 1.1, 1.2, 1.5, 2, 3, 5, 10, 20, 50, 100, 1000, 1e4};
  for (double r : ratios) {
    const double y = std::log10(r);
    if (y < f.y0 || y > f.y1) continue;
    svg += line(f.left, f.py(y), f.left + f.w, f.py(y), "#dddddd", 0.5);
    svg += text_at(f.left - 6, f.py(y) + 4, fmt("%g", r), "end", 11);
  }
  svg += "<text x=\"24\" y=\"" + fmt("%.1f", f.top + f.h / 2) + "\" font-size=\"12\" text-anchor=\"middle\" " +
         "transform=\"rotate(-90 24 " + fmt("%.1f", f.top + f.h / 2) + ")\">energy / lowest final energy of the case (log)</text>\n";
  for (size_t k = 0; k < series.size(); ++k) {
    const char* colour = kPalette[k % kPaletteSize];
    std::string points;
    for (size_t i = 0; i < series[k].t.size(); ++i)
      points += fmt("%.1f", f.px(series[k].t[i])) + "," + fmt("%.1f", f.py(series[k].e[i])) + " ";
    const std::string dash = series[k].dashed ? "\" stroke-dasharray=\"6 3" : "";
    svg += "<polyline fill=\"none\" stroke=\"" + std::string(colour) + dash + "\" stroke-width=\"1.5\" points=\"" +
           points + "\"/>\n";
    const double ly = f.top + 14 + 18 * double(k);
    svg += line(f.left + f.w + 16, ly - 4, f.left + f.w + 40, ly - 4, colour, 2);
    svg += text_at(f.left + f.w + 46, ly, series[k].name, "start", 11);
  }
  if (series.empty()) svg += text_at(f.left + f.w / 2, f.top + f.h / 2, "no CVD or Lloyd run with energies");
  return svg + "</svg>\n";
}

std::string histogram_svg(const std::string& title, const json& rows) {
  const int width = 860, height = 360;
  std::string svg = svg_open(width, height);
  svg += text_at(width / 2.0, 22, title, "middle", 14);
  svg += histogram_panel({70, 50, 320, 230, 0, 1, 0, 1}, rows, "q_histogram", 0, 1, "triangle quality Q", 0.2);
  svg += histogram_panel({500, 50, 320, 230, 0, 1, 0, 1}, rows, "min_angle_histogram", 0, 60,
                         "smallest angle of the triangle (degrees)", 10);
  double x = 70;
  for (size_t k = 0; k < rows.size(); ++k) {
    const std::string name = rows[k].value("algorithm", std::string("?"));
    svg += "<rect x=\"" + fmt("%.1f", x) + "\" y=\"334\" width=\"14\" height=\"10\" fill=\"" +
           kPalette[k % kPaletteSize] + "\"/>\n";
    svg += text_at(x + 20, 344, name, "start", 12);
    x += 40 + 8.0 * double(name.size());
  }
  return svg + "</svg>\n";
}

}  // namespace streamcvd::cli
