#include "dtis/io/report.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/core/version.hpp"
#include "dtis/io/setpoint_file.hpp"

#ifndef DTIS_DATA_FROM_BIN
#define DTIS_DATA_FROM_BIN "../share/dtis"
#endif
#ifndef DTIS_PLOTLY_JS
#define DTIS_PLOTLY_JS ""
#endif

namespace dtis::io {
namespace {

using nlohmann::ordered_json;

constexpr double kDeg = 180.0 / std::numbers::pi;
// Points of the 3D tool path drawn at most, and tool-axis segments in 5-axis.
constexpr std::size_t kPathPoints = 20000;
constexpr std::size_t kAxisSegments = 60;
// The face is drawn this far around the path's box: the larger of an absolute margin and a fraction
// of the box's diagonal.
constexpr double kSurfaceMarginMm = 5.0;
constexpr double kSurfaceMarginFraction = 0.25;

// k-th backward difference of `x` over dt, 0 where it is not defined yet (the rows before the
// first are the first row held, as the verifier reads a file).
std::vector<double> Derivative(const std::vector<double>& x, double dt) {
  std::vector<double> d(x.size(), 0.0);
  for (std::size_t i = 1; i < x.size(); ++i) d[i] = (x[i] - x[i - 1]) / dt;
  return d;
}

// The tool tip (and axis) in the workpiece at each row, from the machine's forward transform, and
// the tip's feed (mm/min) by backward differences.
struct TipPath {
  std::vector<Pose> poses;
  std::vector<double> feed;
};
TipPath Tip(const Machine& machine, const interp::SetpointTable& table, double dt) {
  const std::size_t n = table.Rows();
  const FileUnits units(machine);
  std::vector<double> row(table.columns.size());
  TipPath tip;
  tip.poses.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t i = 0; i < row.size(); ++i) row[i] = table.columns[i][k];
    tip.poses[k] = machine.Forward(units.ToPlanner(row));
  }
  tip.feed.assign(n, 0.0);
  for (std::size_t k = 1; k < n; ++k)
    tip.feed[k] = (tip.poses[k].tip - tip.poses[k - 1].tip).norm() / dt * 60.0;
  return tip;
}

ordered_json Series(const std::vector<double>& t, const std::vector<double>& y) {
  ordered_json xs = ordered_json::array(), ys = ordered_json::array();
  for (std::size_t i : DecimateMinMax(y, kReportPoints)) {
    xs.push_back(t[i]);
    ys.push_back(y[i]);
  }
  return {{"t", std::move(xs)}, {"y", std::move(ys)}};
}

std::string LimiterLabel(const interp::LimiterId& l, const Machine& machine) {
  std::string name = interp::LimiterName(l.kind);
  if (l.axis >= 0 && l.axis < machine.AxisCount()) {
    name = fmt::format("{} {}", machine.Axes()[static_cast<std::size_t>(l.axis)].name, name);
  }
  return name;
}

// The constraint that decided each of `rows` (indices into the table), as points (x, label) with
// x[i] the abscissa of rows[i]: every label that occurs in a bucket once, at its first row there.
ordered_json LimiterBand(const ReportInput& in, const std::vector<std::size_t>& rows,
                         const std::vector<double>& x) {
  ordered_json xs = ordered_json::array(), ys = ordered_json::array();
  std::size_t n = 0;
  while (n < rows.size() && rows[n] < in.limiters.size()) ++n;
  const std::size_t buckets = kReportPoints / 2;
  const std::size_t width = std::max<std::size_t>(1, (n + buckets - 1) / buckets);
  for (std::size_t b = 0; b < n; b += width) {
    std::vector<std::string> seen;
    for (std::size_t i = b; i < std::min(n, b + width); ++i) {
      std::string label = LimiterLabel(in.limiters[rows[i]], *in.machine);
      if (std::find(seen.begin(), seen.end(), label) != seen.end()) continue;
      xs.push_back(x[i]);
      ys.push_back(label);
      seen.push_back(std::move(label));
    }
  }
  return {{"x", std::move(xs)}, {"label", std::move(ys)}};
}

// Rows of a window drawn as one step of an envelope: at least this many, and as many as keep a
// plot to kWindows steps.
constexpr std::size_t kWindowRows = 10;
constexpr std::size_t kWindows = 1000;
std::size_t WindowRows(std::size_t n) {
  return std::max(kWindowRows, (n + kWindows - 1) / kWindows);
}

// Rounded for display (the page needs no more digits than a pixel).
double Display(double v) {
  return std::abs(v) >= 1e-12 ? std::stod(fmt::format("{:.6g}", v)) : 0.0;
}

// `y` in windows of `width` rows: each window's first time, smallest, largest and mean value.
ordered_json Windows(const std::vector<double>& t, const std::vector<double>& y, std::size_t width,
                     bool with_low_and_mean) {
  ordered_json ts = ordered_json::array(), lo = ordered_json::array(), hi = ordered_json::array(),
               mean = ordered_json::array();
  for (std::size_t b = 0; b < y.size(); b += width) {
    const std::size_t e = std::min(y.size(), b + width);
    double l = y[b], h = y[b], sum = 0.0;
    for (std::size_t i = b; i < e; ++i) {
      l = std::min(l, y[i]);
      h = std::max(h, y[i]);
      sum += y[i];
    }
    ts.push_back(t[b]);
    hi.push_back(Display(h));
    if (with_low_and_mean) {
      lo.push_back(Display(l));
      mean.push_back(Display(sum / static_cast<double>(e - b)));
    }
  }
  // The last step ends at the last row.
  if (!y.empty()) {
    ts.push_back(t.back());
    hi.push_back(hi.back());
    if (with_low_and_mean) {
      lo.push_back(lo.back());
      mean.push_back(mean.back());
    }
  }
  ordered_json out = {{"t", std::move(ts)}, {"hi", std::move(hi)}};
  if (with_low_and_mean) {
    out["lo"] = std::move(lo);
    out["mean"] = std::move(mean);
  }
  return out;
}

// |value| / limit in %, and the share of rows at the limit (kAtLimit), in %.
struct Usage {
  std::vector<double> percent;
  double at_limit = 0.0;
};
Usage UsageOf(const std::vector<double>& d, double limit) {
  Usage u;
  u.percent.resize(d.size());
  std::size_t at = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    u.percent[i] = 100.0 * std::abs(d[i]) / limit;
    if (std::abs(d[i]) >= kAtLimit * limit) ++at;
  }
  u.at_limit = d.empty() ? 0.0 : 100.0 * static_cast<double>(at) / static_cast<double>(d.size());
  return u;
}

// "um" as the unit it stands for, for a page (the terminal's tables keep ASCII).
std::string Micro(std::string text) {
  for (std::size_t at = 0; (at = text.find("um", at)) != std::string::npos; at += 2) {
    const bool word_start = at == 0 || !std::isalpha(static_cast<unsigned char>(text[at - 1]));
    const bool word_end =
        at + 2 == text.size() || !std::isalpha(static_cast<unsigned char>(text[at + 2]));
    if (word_start && word_end) text.replace(at, 2, "\u00b5m");
  }
  return text;
}

// A polygon clipped to the box [lo, hi] (Sutherland-Hodgman, one face of the box at a time).
std::vector<Eigen::Vector3d> ClipToBox(std::vector<Eigen::Vector3d> polygon,
                                       const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  for (int axis = 0; axis < 3; ++axis) {
    for (const double sign : {1.0, -1.0}) {
      // Inside: sign * (p[axis] - bound) >= 0.
      const double bound = sign > 0 ? lo[axis] : hi[axis];
      const auto inside = [&](const Eigen::Vector3d& p) { return sign * (p[axis] - bound); };
      std::vector<Eigen::Vector3d> out;
      for (std::size_t i = 0; i < polygon.size(); ++i) {
        const Eigen::Vector3d& a = polygon[i];
        const Eigen::Vector3d& b = polygon[(i + 1) % polygon.size()];
        const double da = inside(a), db = inside(b);
        if (da >= 0) out.push_back(a);
        if ((da >= 0) != (db >= 0)) out.push_back(a + (b - a) * (da / (da - db)));
      }
      polygon = std::move(out);
      if (polygon.empty()) return polygon;
    }
  }
  return polygon;
}

// Text safe inside <script>: no "</" can close the element.
std::string ScriptSafe(std::string text) {
  for (std::size_t at = 0; (at = text.find("</", at)) != std::string::npos; at += 3) {
    text.replace(at, 2, "<\\/");
  }
  return text;
}

constexpr const char* kPage = R"html(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>dtis report: @TITLE@</title>
<style>
body { font-family: system-ui, sans-serif; margin: 1em 1.5em; color: #222; max-width: 1400px; }
h1 { font-size: 1.3em; margin: 0.2em 0 0.5em; } h2 { font-size: 1.05em; margin: 1.2em 0 0.3em; }
table { border-collapse: collapse; font-size: 0.85em; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
#about td { text-align: left; } #about td:first-child { color: #555; }
#about td:last-child { max-width: 36em; overflow-wrap: anywhere; }
.head { display: flex; flex-wrap: wrap; gap: 1.5em; align-items: flex-start; }
.fail { color: #b00; font-weight: bold; } .pass { color: #070; font-weight: bold; }
.plot { width: 100%; } .note { color: #555; font-size: 0.85em; margin: 0.2em 0; }
details > summary { cursor: pointer; font-weight: bold; margin: 1.2em 0 0.3em; }
</style>
<script>@PLOTLY@</script>
</head><body data-report-status="loading" data-console-errors="0">
<h1>dtis report: <span id="title"></span></h1>
<div class="head"><table id="about"></table><table id="summary"></table></div>
<div id="compare-section" hidden>
<h2>Comparison: the same passes from exports and on the exact surface</h2>
<table id="compare"></table><ul id="compare-notes"></ul>
<h2>Feed against time, one panel per variant (shared axes; grey: the exact surface, same planner)</h2>
<p class="note" id="compare-feed-note"></p>
<div id="compare-feed" class="plot"></div>
<h2>Motion time and deviation from the exact path</h2>
<div id="compare-bars" class="plot"></div>
<h2 id="shown"></h2>
</div>
<div id="unreachable-section" hidden><h2>Left out where the tool does not fit</h2>
<pre id="unreachable"></pre></div>
<h2 id="path-title">Tool path, coloured by feed</h2><div id="path" class="plot"></div>
<h2 id="feed-title">Feed against time, and the constraint that decided each period</h2>
<p class="note" id="feed-note"></p>
<div id="feed" class="plot"></div>
<h2>How close each axis comes to its limits</h2>
<p class="note">|value| / limit per axis, the largest in each window of @WINDOW@ periods, and the share of periods each axis spends at the limit (at least @AT_LIMIT@ % of it).</p>
<div id="usage" class="plot"></div>
<details id="raw"><summary>Each axis' position, velocity, acceleration and jerk</summary>
<p class="note">Jerk: the band between the smallest and the largest in each window of @WINDOW@ periods, and its mean. Limits are drawn where the values come near them.</p>
<div id="axes"></div></details>
<div id="figures" hidden></div>
<script>
const DATA = @DATA@;
window.addEventListener('error', e => { document.body.dataset.reportStatus = 'error: ' + e.message; });
// Console errors are counted on the page, so a headless browser's test can read them.
const consoleError = console.error.bind(console);
console.error = (...args) => { document.body.dataset.consoleErrors = (+document.body.dataset.consoleErrors || 0) + 1; consoleError(...args); };
function row(cells, head) {
  const tr = document.createElement('tr');
  for (const c of cells) { const td = document.createElement(head ? 'th' : 'td'); td.textContent = c; tr.appendChild(td); }
  return tr;
}
const pct = v => v.toFixed(1) + ' %';
function summary() {
  const s = DATA.summary, t = document.getElementById('summary');
  document.getElementById('title').textContent = DATA.title;
  for (const [k, v] of DATA.about) document.getElementById('about').appendChild(row([k, v]));
  const kv = [['motion time', s.motion_time_s.toFixed(6) + ' s'], ['setpoints', s.setpoints + ' at ' + (s.period_s * 1e3) + ' ms'],
              ['worst ratio', s.worst_ratio.toFixed(9) + ' (' + s.worst + ')'], ['verifier', s.passed ? 'PASS' : 'FAIL']];
  if (s.passes > 0) kv.push(['passes', String(s.passes)]);
  if (s.compute_s >= 0) kv.push(['compute time', s.compute_s.toFixed(3) + ' s']);
  for (const [k, v] of kv) { const r = row([k, v]); if (k === 'verifier') r.lastChild.className = s.passed ? 'pass' : 'fail'; r.lastChild.colSpan = 6; t.appendChild(r); }
  t.appendChild(row(['axis', '|v| / limit', '|a| / limit', '|j| / limit', 'at v limit', 'at a limit', 'at j limit'], true));
  s.axes.forEach((a, k) => t.appendChild(row([a.name, a.v_ratio.toFixed(6), a.a_ratio.toFixed(6), a.j_ratio.toFixed(6),
    ...DATA.axes[k].at_limit.map(pct)])));
  if (DATA.unreachable) {
    document.getElementById('unreachable').textContent = DATA.unreachable;
    document.getElementById('unreachable-section').hidden = false;
  }
}

// Every plot is built twice from the same data: for the page, and for print (dtis figures) at a
// column's width with smaller fonts. build(print, width) gives { data, layout, height }.
const PRINT_FONT = 11, SCREEN_FONT = 12;
const AXIS_COLORS = { X: '#0072B2', Y: '#E69F00', Z: '#009E73', A: '#CC79A7', B: '#56B4E9', C: '#D55E00', U: '#F0E442', V: '#000000', W: '#999999' };
const PALETTE = ['#0072B2', '#E69F00', '#009E73', '#CC79A7', '#56B4E9', '#D55E00', '#000000', '#999999'];
const axisColor = (name, k) => AXIS_COLORS[name] || PALETTE[k % PALETTE.length];
const CONFIG = { responsive: true, displaylogo: false,
  modeBarButtonsToRemove: ['select2d', 'lasso2d', 'autoScale2d', 'toggleSpikelines', 'hoverClosestCartesian', 'hoverCompareCartesian'] };
function baseLayout(print, margin) {
  return { font: { family: 'Helvetica, Arial, sans-serif', size: print ? PRINT_FONT : SCREEN_FONT, color: '#222' },
    margin: Object.assign({ t: print ? 8 : 34, r: print ? 8 : 20, b: print ? 30 : 45, l: print ? 44 : 70 }, margin || {}),
    paper_bgcolor: 'white', plot_bgcolor: 'white', showlegend: false };
}
// Legends sit above the plot on the left; the toolbar is on the right.
const topLegend = print => ({ orientation: 'h', x: 0, xanchor: 'left', y: 1, yanchor: 'bottom', font: { size: print ? PRINT_FONT - 1 : SCREEN_FONT - 1 },
  itemwidth: 30, tracegroupgap: 0 });
const grid = { showgrid: true, gridcolor: '#e6e6e6', zeroline: false, linecolor: '#888', showline: true, ticks: 'outside', ticklen: 3 };
const axisTitle = text => ({ text, standoff: 4 });
const PLOTS = [];  // { name, div, build }, in the order of the page
const maxOf = a => a.reduce((m, v) => Math.max(m, v), -Infinity);
const minOf = a => a.reduce((m, v) => Math.min(m, v), Infinity);

// A variant's name with what it says in parentheses on a line of its own, so names fit a column.
const twoLines = name => name.replace(' (', '<br>(');
// The comparison: one panel per variant (planners by rows, exports by columns on the page;
// transposed in print), shared axes, the exact surface's feed in grey under each.
function compareFeed(print, width) {
  const c = DATA.compare, feeds = c.feeds;
  const variants = [...new Set(feeds.map(f => f.variant))], planners = [...new Set(feeds.map(f => f.planner))];
  const rows = print ? variants.length : planners.length, cols = print ? planners.length : variants.length;
  const cell = (r, col) => print ? [variants[r], planners[col]] : [variants[col], planners[r]];
  const t1 = maxOf(feeds.map(f => maxOf(f.t))), f1 = (print ? 1.6 : 1.06) * maxOf(feeds.map(f => maxOf(f.y)));
  // On the page, room for two-line panel titles under the toolbar.
  const layout = baseLayout(print, { t: print ? 16 : 72, l: print ? 54 : 90 }), data = [], annotations = [];
  const gx = print ? 0.04 : 0.025, gy = print ? 0.06 : 0.12;
  for (let r = 0; r < rows; ++r) for (let col = 0; col < cols; ++col) {
    const [variant, planner] = cell(r, col), k = r * cols + col + 1, xa = 'x' + (k > 1 ? k : ''), ya = 'y' + (k > 1 ? k : '');
    const f = feeds.find(v => v.variant === variant && v.planner === planner);
    const exact = feeds.find(v => v.planner === planner && v.exact);
    if (exact && exact !== f) data.push({ type: 'scatter', mode: 'lines', name: exact.name, x: exact.t, y: exact.y, xaxis: xa, yaxis: ya,
      line: { color: '#bbbbbb', width: 1 }, hoverinfo: 'skip' });
    if (f) data.push({ type: 'scatter', mode: 'lines', name: f.name, x: f.t, y: f.y, xaxis: xa, yaxis: ya, line: { color: '#0072B2', width: 1.2 },
      hovertemplate: f.name + '<br>t %{x:.3f} s<br>feed %{y:.0f} mm/min<extra></extra>' });
    const x0 = col / cols + (col ? gx / 2 : 0), x1 = (col + 1) / cols - (col < cols - 1 ? gx / 2 : 0);
    const y1 = 1 - r / rows - (r ? gy / 2 : 0), y0 = 1 - (r + 1) / rows + (r < rows - 1 ? gy / 2 : 0);
    layout['xaxis' + (k > 1 ? k : '')] = Object.assign({}, grid, { domain: [x0, x1], range: [0, t1], anchor: ya, matches: k > 1 ? 'x' : undefined,
      showticklabels: r === rows - 1, title: r === rows - 1 ? axisTitle('t (s)') : undefined });
    // In print the variant names each panel (the column names the planner); on the page the row
    // names the planner (the column the variant).
    const yTitle = print ? (r === Math.floor(rows / 2) ? 'feed (mm/min)' : '') : planner + '<br>feed (mm/min)';
    layout['yaxis' + (k > 1 ? k : '')] = Object.assign({}, grid, { domain: [y0, y1], range: [0, f1], anchor: xa, matches: k > 1 ? 'y' : undefined,
      showticklabels: col === 0, title: col === 0 ? axisTitle(yTitle) : undefined });
    if (print && f) annotations.push({ text: variant + '<br>' + f.time_s.toFixed(2) + ' s', xref: xa + ' domain', yref: ya + ' domain', x: 1, y: 1,
      xanchor: 'right', yanchor: 'top', align: 'right', showarrow: false, font: { size: PRINT_FONT - 1 } });
    if (r === 0) annotations.push({ text: print ? planner : twoLines(variant), xref: 'paper', yref: 'paper', x: (x0 + x1) / 2, y: 1, yanchor: 'bottom', showarrow: false,
      font: { size: (print ? PRINT_FONT : SCREEN_FONT) } });
    if (f && !print) annotations.push({ text: f.time_s.toFixed(2) + ' s', xref: xa + ' domain', yref: ya + ' domain', x: 0.98, y: print ? 1 : 0.96, xanchor: 'right', yanchor: 'top',
      showarrow: false, font: { size: (print ? PRINT_FONT : SCREEN_FONT) - 1, color: '#555' } });
  }
  layout.annotations = annotations;
  return { data, layout, height: print ? Math.round(rows * width * 0.2 + 50) : rows * 210 + 90 };
}
// Motion time and deviation per variant, one bar colour per planner.
function compareBars(print, width) {
  const feeds = DATA.compare.feeds, planners = [...new Set(feeds.map(f => f.planner))];
  const colors = ['#0072B2', '#E69F00', '#009E73'], data = [];
  planners.forEach((p, k) => {
    const mine = feeds.filter(f => f.planner === p);
    for (const [axis, key, digits] of [['y', 'time_s', 2], ['y2', 'motion_dev_um', 2]]) {
      data.push({ type: 'bar', name: p, legendgroup: p, showlegend: axis === 'y', x: mine.map(f => twoLines(f.variant)), y: mine.map(f => f[key]),
        xaxis: axis === 'y' ? 'x' : 'x2', yaxis: axis, marker: { color: colors[k % colors.length] },
        text: print ? undefined : mine.map(f => f[key].toFixed(digits)), textposition: 'outside', cliponaxis: false, textfont: { size: (print ? PRINT_FONT : SCREEN_FONT) - 2 } });
    }
  });
  const layout = baseLayout(print, { t: print ? 24 : 40, b: print ? 60 : 70 });
  layout.showlegend = true;
  layout.legend = topLegend(print);
  layout.barmode = 'group';
  const split = print ? [[0, 1], [0, 1]] : [[0, 0.46], [0.54, 1]];
  layout.xaxis = Object.assign({}, grid, { domain: split[0], anchor: 'y', tickangle: print ? -30 : 0, showgrid: false, automargin: true });
  layout.xaxis2 = Object.assign({}, grid, { domain: split[1], anchor: 'y2', tickangle: print ? -30 : 0, showgrid: false, automargin: true });
  layout.yaxis = Object.assign({}, grid, { anchor: 'x', title: axisTitle('motion time (s)'), rangemode: 'tozero', domain: print ? [0.58, 1] : [0, 1] });
  layout.yaxis2 = Object.assign({}, grid, { anchor: 'x2', title: axisTitle('deviation (µm)'), rangemode: 'tozero', domain: print ? [0, 0.36] : [0, 1] });
  if (print) layout.xaxis.showticklabels = false;
  return { data, layout, height: print ? Math.round(width * 0.95) : 380 };
}
function compareSection() {
  const c = DATA.compare;
  if (!c) return;
  document.getElementById('compare-section').hidden = false;
  const t = document.getElementById('compare');
  t.appendChild(row(c.header, true));
  for (const r of c.rows) t.appendChild(row(r));
  for (const n of c.notes) { const li = document.createElement('li'); li.textContent = 'note: ' + n; document.getElementById('compare-notes').appendChild(li); }
  document.getElementById('shown').textContent = 'The run in full: ' + c.shown;
  document.getElementById('shown').after(document.getElementById('summary'));
  const f1 = maxOf(c.feeds.map(f => maxOf(f.y)));
  document.getElementById('compare-feed-note').textContent = DATA.programmed_feed > 0
    ? 'programmed feed ' + DATA.programmed_feed.toFixed(0) + ' mm/min; the fastest variant reaches ' + f1.toFixed(0) + ' mm/min' : '';
  PLOTS.push({ name: 'compare-feed', div: 'compare-feed', build: compareFeed });
  PLOTS.push({ name: 'compare-bars', div: 'compare-bars', build: compareBars });
}
// The 3-D view needs WebGL; without it (a locked-down browser, a remote desktop) the path is drawn
// from above in SVG, coloured by feed the same way.
function hasWebGL() {
  try { const c = document.createElement('canvas'); return !!(c.getContext('webgl') || c.getContext('experimental-webgl')); }
  catch (e) { return false; }
}
const feedColor = (print, values) => ({ color: values, colorscale: 'Viridis', cmin: 0, cmax: Math.max(1, maxOf(values)), showscale: true,
  colorbar: { title: { text: 'feed (mm/min)', side: 'right' }, thickness: print ? 10 : 16, len: 0.9, outlinewidth: 0, tickfont: { size: print ? PRINT_FONT - 1 : SCREEN_FONT - 1 } } });
// From above: the face's outline in grey, the tool tip coloured by feed (vector throughout).
function pathTop(print, width) {
  const p = DATA.path, every = Math.max(1, Math.ceil(p.x.length / 4000)), pick = a => a.filter((_, i) => i % every === 0), data = [];
  if (DATA.surface) data.push({ type: 'scatter', mode: 'lines', name: 'face outline', x: DATA.surface.outline.x, y: DATA.surface.outline.y,
    line: { color: '#aaaaaa', width: 1 }, hoverinfo: 'skip' });
  data.push({ type: 'scatter', mode: 'markers', name: 'tool tip', x: pick(p.x), y: pick(p.y), marker: Object.assign({ size: print ? 2 : 3 }, feedColor(print, pick(p.feed))),
    hovertemplate: 'x %{x:.3f}<br>y %{y:.3f}<br>feed %{marker.color:.0f} mm/min<extra></extra>' });
  const layout = baseLayout(print, { t: 10 });
  layout.xaxis = Object.assign({}, grid, { title: axisTitle('x (mm)'), constrain: 'domain' });
  layout.yaxis = Object.assign({}, grid, { title: axisTitle('y (mm)'), scaleanchor: 'x', constrain: 'domain' });
  // As tall as the path is deep at that width (the colour bar takes a sixth of it).
  const xs = p.x.concat(DATA.surface ? DATA.surface.outline.x.filter(v => v !== null) : []);
  const ys = p.y.concat(DATA.surface ? DATA.surface.outline.y.filter(v => v !== null) : []);
  const aspect = (maxOf(ys) - minOf(ys)) / Math.max(1e-9, maxOf(xs) - minOf(xs));
  const plotW = width * 0.8 - layout.margin.l, h = Math.min(1.2 * width, Math.max(0.45 * width, aspect * plotW + layout.margin.t + layout.margin.b));
  return { data, layout, height: Math.round(print ? h : Math.min(700, Math.max(400, h))) };
}
// A path in a plane z = constant (most G-code and curves) reads best from above.
function flatPath() {
  const p = DATA.path, span = a => maxOf(a) - minOf(a);
  return !DATA.surface && !p.axis && span(p.z) <= 0.01 * Math.max(span(p.x), span(p.y));
}
const path3d = () => hasWebGL() && !flatPath();
function pathPlot(print, width) {
  const p = DATA.path;
  if (!path3d()) return pathTop(print, width);
  const data = [];
  if (DATA.surface) { const f = DATA.surface; data.push({ type: 'mesh3d', name: 'surface', x: f.x, y: f.y, z: f.z, i: f.i, j: f.j, k: f.k,
    color: '#c9ced6', opacity: 0.7, flatshading: false, hoverinfo: 'skip', lighting: { ambient: 0.75, diffuse: 0.45, specular: 0.05 } }); }
  data.push({ type: 'scatter3d', mode: 'lines', name: 'tool tip', x: p.x, y: p.y, z: p.z, line: Object.assign({ width: print ? 3 : 5 }, feedColor(print, p.feed)),
    hovertemplate: 'x %{x:.3f}<br>y %{y:.3f}<br>z %{z:.3f}<br>feed %{line.color:.0f} mm/min<extra></extra>' });
  if (p.axis) data.push({ type: 'scatter3d', mode: 'lines', name: 'tool axis', x: p.axis.x, y: p.axis.y, z: p.axis.z,
    line: { width: print ? 1 : 2, color: '#555' }, hoverinfo: 'skip' });
  const layout = baseLayout(print, { t: 0, l: 0, r: 0, b: 0 });
  const title = text => ({ title: { text }, tickfont: { size: print ? PRINT_FONT - 2 : SCREEN_FONT - 1 } });
  // True proportions in a box whose longest side is 1, so the camera sees all of a long, thin path
  // (plotly's 'data' aspect scales the box to a unit volume instead).
  const pts = k => [p, DATA.surface, p.axis].filter(Boolean).flatMap(o => o[k].filter(v => v !== null));
  const lo = ['x', 'y', 'z'].map(k => minOf(pts(k))), hi = ['x', 'y', 'z'].map(k => maxOf(pts(k)));
  const longest = Math.max(1e-9, ...hi.map((h, i) => h - lo[i])), pad = 0.02 * longest;
  const side = i => Math.max(hi[i] - lo[i] + 2 * pad, 1e-3 * longest) / (longest + 2 * pad);
  const axis3 = (i, text) => Object.assign(title(text), { range: [lo[i] - pad, hi[i] + pad] });
  // The camera as far from a thin box as from a cube of its diagonal.
  const near = Math.max(0.55, Math.hypot(side(0), side(1), side(2)) / Math.sqrt(3)) * (print ? 1.15 : 1.3);
  layout.scene = { aspectmode: 'manual', aspectratio: { x: side(0), y: side(1), z: side(2) },
    camera: { eye: { x: near, y: near, z: 0.75 * near } },
    xaxis: axis3(0, 'x (mm)'), yaxis: axis3(1, 'y (mm)'), zaxis: axis3(2, 'z (mm)') };
  if (print) layout.scene.domain = { x: [0, 0.85], y: [0, 1] };
  return { data, layout, height: print ? Math.round(width * 0.8) : 600 };
}
// The feed (along the passes when the report knows them, else against time) and under it the
// constraint that decided each period.
function feedPlot(print, width) {
  const along = DATA.pass_feed, f = along ? { x: along.s, y: along.y } : { x: DATA.feed.t, y: DATA.feed.y };
  const band = along ? along.limiters : DATA.limiters, labels = [...new Set(band.label)];
  const data = [{ type: 'scatter', mode: 'lines', name: 'feed', x: f.x, y: f.y, line: { color: '#0072B2', width: print ? 1 : 1.5 } }];
  const x0 = f.x[0], x1 = f.x[f.x.length - 1];
  if (DATA.programmed_feed > 0) data.push({ type: 'scatter', mode: 'lines', name: print ? 'programmed' : 'programmed feed',
    x: [x0, x1], y: [DATA.programmed_feed, DATA.programmed_feed], line: { color: '#D55E00', dash: 'dash', width: 1 } });
  if (band.x.length) data.push({ type: 'scatter', mode: 'markers', name: 'deciding constraint', showlegend: false, x: band.x, y: band.label, yaxis: 'y2',
    marker: { size: print ? 2.5 : 4, symbol: 'square', color: '#444' } });
  const row = print ? 11 : 17, top = print ? 0.62 * width : 300, bandH = band.x.length ? labels.length * row + 8 : 0;
  const height = Math.round(top + bandH + (print ? 50 : 90)), split = bandH / (top + bandH);
  const layout = baseLayout(print, { t: print ? 22 : 50 });
  layout.showlegend = true;
  layout.legend = topLegend(print);
  layout.xaxis = Object.assign({}, grid, { title: axisTitle(along ? 'arc length along the passes (mm)' : 't (s)'), anchor: band.x.length ? 'y2' : 'y' });
  if (along && feedRange) layout.xaxis.range = feedRange;
  layout.yaxis = Object.assign({}, grid, { title: axisTitle('feed (mm/min)'), domain: band.x.length ? [split + 0.06, 1] : [0, 1], rangemode: 'tozero' });
  layout.yaxis2 = Object.assign({}, grid, { domain: [0, split], type: 'category', categoryorder: 'array', categoryarray: labels,
    automargin: true, tickfont: { size: print ? PRINT_FONT - 2 : SCREEN_FONT - 1 }, showgrid: false, range: [-0.6, labels.length - 0.4],
    tickmode: 'array', tickvals: labels, ticktext: labels });
  if (along) {
    // Pass boundaries, and each pass' number (every k-th where they would crowd).
    const passes = along.passes, every = Math.max(1, Math.ceil(passes.length / (print ? 12 : 40)));
    layout.shapes = passes.slice(1).map(p => ({ type: 'line', xref: 'x', yref: 'paper', x0: p.s0, x1: p.s0, y0: 0, y1: 1,
      line: { color: '#999', width: 0.6, dash: 'dot' } }));
    layout.annotations = passes.map((p, k) => ({ k, p })).filter(({ k, p }) => k % every === 0 || passes.length < 2 || (feedRange && p.s0 === feedRange[0])).map(({ k, p }) => ({
      text: String(k + 1), x: (p.s0 + p.s1) / 2, xref: 'x', y: 1, yref: 'paper', yanchor: 'bottom', showarrow: false,
      font: { size: (print ? PRINT_FONT : SCREEN_FONT) - 2, color: '#666' } }));
    if (passes.length > 1) layout.legend.x = 0.0, layout.legend.y = 1.06;
  }
  return { data, layout, height };
}
// The arc lengths one pass spans (k from 0), or null for every pass.
let feedRange = null;
function passRange(k) {
  const p = DATA.pass_feed && k !== '' ? DATA.pass_feed.passes[+k] : undefined;
  return p ? [p.s0, p.s1] : null;
}
function feedSection() {
  const along = DATA.pass_feed;
  if (along) {
    const n = along.passes.length;
    document.getElementById('feed-title').textContent = 'Feed along the passes, and the constraint that decided each period';
    const note = document.getElementById('feed-note');
    note.textContent = n + (n === 1 ? ' pass' : ' passes, numbered above the plot; dotted lines where one ends and the next begins') +
      '. The links between them (' + along.link_time_s.toFixed(3) + ' s) are left out. ';
    if (n > 1) {
      const select = document.createElement('select');
      select.id = 'pass';
      select.appendChild(new Option('every pass', ''));
      along.passes.forEach((p, k) => select.appendChild(new Option('pass ' + (k + 1) + ' (' + (p.t1 - p.t0).toFixed(3) + ' s, ' + (p.s1 - p.s0).toFixed(1) + ' mm)', k)));
      select.addEventListener('change', () => {
        feedRange = passRange(select.value);
        Plotly.relayout('feed', feedRange ? { 'xaxis.range': feedRange } : { 'xaxis.autorange': true });
      });
      // #pass=N in the address shows pass N (and draws its figure so: dtis figures --pass N).
      if (wanted.has('pass')) {
        select.value = String(+wanted.get('pass') - 1);
        feedRange = passRange(select.value);
      }
      const label = document.createElement('label');
      label.append('Show: ', select);
      note.appendChild(label);
    }
  }
  PLOTS.push({ name: 'feed', div: 'feed', build: feedPlot });
}
const DERIVATIVES = [['velocity', 'v'], ['acceleration', 'a'], ['jerk', 'j']];
// |value| / limit, 0 to 100 %, one panel per derivative, every axis in each.
function usagePlot(print, width) {
  const data = [], layout = baseLayout(print, { t: print ? 22 : 40 }), gap = print ? 0.07 : 0.06, h = (1 - 2 * gap) / 3, annotations = [];
  layout.showlegend = true;
  layout.legend = topLegend(print);
  DERIVATIVES.forEach(([name, short], d) => {
    const ya = d ? 'y' + (d + 1) : 'y', xa = d ? 'x' + (d + 1) : 'x';
    DATA.axes.forEach((a, k) => {
      const u = a.usage[name];
      data.push({ type: 'scatter', mode: 'lines', name: a.name, legendgroup: a.name, showlegend: d === 0, x: u.t, y: u.hi, xaxis: xa, yaxis: ya,
        line: { color: axisColor(a.name, k), width: print ? 1 : 1.4, shape: 'hv' },
        hovertemplate: a.name + ' ' + name + ' %{y:.1f} % of its limit at t %{x:.3f} s<br>at the limit ' + pct(a.at_limit[d]) + ' of the periods<extra></extra>' });
    });
    const y1 = 1 - d * (h + gap), y0 = y1 - h;
    // The share of periods each axis spends at this limit, largest first.
    const shares = DATA.axes.map(a => [a.name, a.at_limit[d]]).filter(([, v]) => v >= 0.05).sort((p, q) => q[1] - p[1]);
    annotations.push({ text: 'periods at the limit: ' + (shares.length ? shares.map(([n, v]) => n + ' ' + pct(v)).join(', ') : 'none'),
      xref: xa + ' domain', yref: ya + ' domain', x: 1, y: 1, xanchor: 'right', yanchor: 'top', showarrow: false,
      bgcolor: 'rgba(255, 255, 255, 0.8)', font: { size: (print ? PRINT_FONT : SCREEN_FONT) - 1, color: '#444' } });
    layout['yaxis' + (d ? d + 1 : '')] = Object.assign({}, grid, { domain: [y0, y1], range: [0, 130], tickvals: [0, 50, 100], anchor: xa,
      title: axisTitle('|' + short + '| / ' + short + '<sub>max</sub> (%)') });
    layout['xaxis' + (d ? d + 1 : '')] = Object.assign({}, grid, { anchor: ya, matches: d ? 'x' : undefined, showticklabels: d === 2,
      title: d === 2 ? axisTitle('t (s)') : undefined });
  });
  layout.annotations = annotations;
  return { data, layout, height: print ? Math.round(width * 0.95) : 560 };
}
// One axis' values: position, velocity, acceleration, and the jerk as a band (the smallest and the
// largest of each window) with its mean. Ranges fit the values; a limit is drawn where the values
// come within half of it.
function axisPlot(a, print, width) {
  const units = [a.unit, a.unit + '/s', a.unit + '/s²', a.unit + '/s³'], names = ['position', 'velocity', 'acceleration', 'jerk'];
  const data = [], layout = baseLayout(print, { t: print ? 14 : 34 }), gap = 0.04, h = (1 - 3 * gap) / 4;
  const limits = [null, a.vmax, a.amax, a.jmax];
  for (let k = 0; k < 4; ++k) {
    const ya = k ? 'y' + (k + 1) : 'y', line = { color: '#0072B2', width: print ? 0.8 : 1.2 };
    let lo, hi;
    if (k < 3) {
      const s = a[names[k]];
      data.push({ type: 'scatter', mode: 'lines', name: names[k], x: s.t, y: s.y, yaxis: ya, line });
      lo = minOf(s.y); hi = maxOf(s.y);
    } else {
      const j = a.jerk;
      data.push({ type: 'scatter', mode: 'lines', name: 'jerk, smallest', x: j.t, y: j.lo, yaxis: ya, line: { width: 0, shape: 'hv' }, hoverinfo: 'skip' });
      data.push({ type: 'scatter', mode: 'lines', name: 'jerk, largest', x: j.t, y: j.hi, yaxis: ya, line: { width: 0, shape: 'hv' }, fill: 'tonexty',
        fillcolor: 'rgba(0, 114, 178, 0.35)', hoverinfo: 'skip' });
      data.push({ type: 'scatter', mode: 'lines', name: 'jerk, mean', x: j.t, y: j.mean, yaxis: ya, line: { color: '#003d66', width: print ? 0.8 : 1.2, shape: 'hv' } });
      lo = minOf(j.lo); hi = maxOf(j.hi);
    }
    const lim = limits[k];
    if (lim !== null) {
      for (const sign of [1, -1]) data.push({ type: 'scatter', mode: 'lines', name: (sign > 0 ? '+' : '-') + 'limit', x: [a.position.t[0], a.position.t[a.position.t.length - 1]],
        y: [sign * lim, sign * lim], yaxis: ya, line: { color: '#D55E00', dash: 'dash', width: 1 }, hoverinfo: 'skip' });
      if (Math.max(Math.abs(lo), Math.abs(hi)) >= 0.5 * lim) { lo = Math.min(lo, -lim); hi = Math.max(hi, lim); }
    }
    const pad = 0.06 * Math.max(hi - lo, 1e-9);
    layout['yaxis' + (k ? k + 1 : '')] = Object.assign({}, grid, { domain: [1 - (k + 1) * h - k * gap, 1 - k * (h + gap)], range: [lo - pad, hi + pad],
      title: axisTitle(print ? (k ? 'vaj'[k - 1] : a.name) + ' (' + units[k] + ')' : names[k] + '<br>(' + units[k] + ')'), automargin: true, zeroline: true, zerolinecolor: '#ccc' });
  }
  layout.xaxis = Object.assign({}, grid, { title: axisTitle('t (s)'), anchor: 'y4' });
  if (!print) layout.title = { text: 'axis ' + a.name + (a.vmax ? '; limits ±' + [a.vmax, a.amax, a.jmax].map(v => +v.toPrecision(4)).join(', ±') : ''), x: 0, font: { size: SCREEN_FONT + 1 } };
  return { data, layout, height: print ? Math.round(width * 1.1) : 720 };
}
function axesSection() {
  for (const a of DATA.axes) {
    const div = document.createElement('div'); div.className = 'plot'; div.id = 'axis-' + a.name;
    document.getElementById('axes').appendChild(div);
    PLOTS.push({ name: 'axis-' + a.name, div: div.id, build: (print, width) => axisPlot(a, print, width), raw: true });
  }
}
// Titles and ticks at the plot's font size (plotly draws axis titles larger).
function finish(fig, print) {
  const size = print ? PRINT_FONT : SCREEN_FONT, scene = fig.layout.scene;
  const axes = Object.keys(fig.layout).filter(k => /^[xy]axis[0-9]*$/.test(k)).map(k => fig.layout[k]);
  if (scene) axes.push(scene.xaxis, scene.yaxis, scene.zaxis);
  for (const a of axes) {
    if (a.title) a.title.font = Object.assign({ size }, a.title.font || {});
    a.tickfont = Object.assign({ size: size - 1 }, a.tickfont || {});
  }
  return fig;
}
function draw(plot) {
  const div = document.getElementById(plot.div), fig = finish(plot.build(false, div.clientWidth || 1200), false);
  div.style.height = fig.height + 'px';
  plot.drawn = true;
  return Plotly.newPlot(div, fig.data, fig.layout, CONFIG);
}
// Whether a plot's legend or one of its annotations (panel titles, notes) overlaps its toolbar,
// box against box, for a browser's test.
function legendOverToolbar(div) {
  const bar = div.querySelector('.modebar');
  if (!bar) return false;
  const b = bar.getBoundingClientRect();
  return [...div.querySelectorAll('.legend, .annotation')].some(e => {
    const a = e.getBoundingClientRect();
    return a.width > 0 && b.width > 0 && a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom;
  });
}

// Static figures (dtis figures): with #figures=png,svg&width_mm=88&dpi=300 in the address, every
// plot is built for print and exported with Plotly.toImage, base64 in a pre element of #figures
// that a headless browser's DOM dump carries out (io/src/figures.cpp reads them). Sizes are CSS
// pixels, 96 to the inch: a figure width_mm wide is laid out that wide and PNGs are scaled to dpi.
function base64(text) {
  const bytes = new TextEncoder().encode(text);
  let binary = '';
  for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(binary);
}
async function figures(formats, widthMm, dpi) {
  const out = document.getElementById('figures'), width = Math.round(widthMm / 25.4 * 96);
  for (const plot of PLOTS) {
    const fig = finish(plot.build(true, width), true);
    for (const format of formats) {
      const url = await Plotly.toImage({ data: fig.data, layout: fig.layout, config: { staticPlot: true } },
        { format, width, height: fig.height, scale: format === 'svg' ? 1 : dpi / 96 });
      const payload = url.slice(url.indexOf(',') + 1);
      const pre = document.createElement('pre');
      pre.className = 'figure';
      pre.dataset.name = plot.name;
      pre.dataset.format = format;
      pre.dataset.widthMm = widthMm;
      pre.dataset.heightMm = (fig.height / 96 * 25.4).toFixed(2);
      pre.textContent = format === 'svg' ? base64(decodeURIComponent(payload)) : payload;
      out.appendChild(pre);
    }
  }
}
const wanted = new URLSearchParams(location.hash.slice(1));
summary();
compareSection();
PLOTS.push({ name: 'path', div: 'path', build: pathPlot });
if (path3d()) PLOTS.push({ name: 'path-top', build: pathTop, printOnly: true });
if (flatPath()) document.getElementById('path-title').textContent = 'Tool path from above (it lies in a plane), coloured by feed';
else if (!hasWebGL()) document.getElementById('path-title').textContent = 'Tool path from above, coloured by feed (the 3-D view needs WebGL, which this browser does not offer)';
feedSection();
PLOTS.push({ name: 'usage', div: 'usage', build: usagePlot });
axesSection();
// The raw values are drawn when asked for (opening them, or #raw / #figures in the address).
const raw = document.getElementById('raw');
if (wanted.has('raw') || wanted.has('figures')) raw.open = true;
raw.addEventListener('toggle', () => { if (raw.open) for (const p of PLOTS) if (p.raw && !p.drawn) draw(p); });
Promise.all(PLOTS.filter(p => !p.printOnly && (!p.raw || raw.open)).map(draw)).then(async plots => {
  document.body.dataset.traces = plots.reduce((n, p) => n + p.data.length, 0);
  document.body.dataset.plots = plots.length;
  // 2-D plots drawn in SVG with every trace there, for a browser's test with WebGL on or off.
  document.body.dataset.drawn2d = plots.filter(p => p.querySelector('.cartesianlayer') &&
    p.querySelectorAll('.scatterlayer .trace, .barlayer .trace').length === p.data.length).length;
  document.body.dataset.webgl = hasWebGL() ? 'yes' : 'no';
  document.body.dataset.path3d = path3d() ? 'yes' : 'no';
  const feedDiv = document.getElementById('feed');
  if (feedRange) document.body.dataset.feedRange = feedDiv.layout.xaxis.range.map(v => v.toFixed(6)) + ' of ' + feedRange.map(v => v.toFixed(6));
  document.body.dataset.colorbars = document.querySelectorAll('#path .colorbar').length;
  document.body.dataset.legendOverToolbar = plots.filter(legendOverToolbar).length;
  if (wanted.has('figures')) {
    await figures(wanted.get('figures').split(','), +(wanted.get('width_mm') || 88), +(wanted.get('dpi') || 300));
    document.body.dataset.figures = 'done';
  }
  if (document.body.dataset.reportStatus === 'loading') document.body.dataset.reportStatus = 'ok';
}).catch(e => { document.body.dataset.reportStatus = 'error: ' + e; });
</script></body></html>
)html";

void ReplaceOnce(std::string& text, const std::string& key, const std::string& value) {
  const auto at = text.find(key);
  if (at != std::string::npos) text.replace(at, key.size(), value);
}

std::string HtmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace

std::vector<std::size_t> DecimateMinMax(const std::vector<double>& values, std::size_t points) {
  const std::size_t n = values.size();
  std::vector<std::size_t> keep;
  if (n <= std::max<std::size_t>(points, 2)) {
    for (std::size_t i = 0; i < n; ++i) keep.push_back(i);
    return keep;
  }
  const std::size_t buckets = std::max<std::size_t>(1, points / 2);
  keep.push_back(0);
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t lo = b * n / buckets, hi = (b + 1) * n / buckets;
    if (lo >= hi) continue;
    std::size_t imin = lo, imax = lo;
    for (std::size_t i = lo; i < hi; ++i) {
      if (values[i] < values[imin]) imin = i;
      if (values[i] > values[imax]) imax = i;
    }
    for (std::size_t i : {std::min(imin, imax), std::max(imin, imax)}) {
      if (i != keep.back()) keep.push_back(i);
    }
  }
  if (keep.back() != n - 1) keep.push_back(n - 1);
  return keep;
}

std::string RenderReport(const ReportInput& in, const std::string& plotly_js) {
  const Machine& machine = *in.machine;
  const interp::SetpointTable& table = *in.table;
  // Verify checks that the table's axes are the machine's; a run's own report already did.
  const interp::VerifyReport verify = in.verify ? *in.verify : interp::Verify(table, machine);
  const std::size_t n = table.Rows();
  const double dt = verify.period_s;
  const auto axes = machine.Axes();

  const auto [poses, feed] = Tip(machine, table, dt);

  ordered_json data;
  data["title"] = in.title;
  ordered_json about = ordered_json::array();
  for (const auto& [key, value] : in.about) about.push_back({key, value});
  about.push_back({"dtis", std::string(kVersion)});
  about.push_back(
      {"made", fmt::format("{:%Y-%m-%d %H:%M:%S %z}", fmt::localtime(std::time(nullptr)))});
  data["about"] = std::move(about);
  data["programmed_feed"] = in.programmed_feed_mm_min;
  data["unreachable"] = in.unreachable;
  ordered_json summary = {{"motion_time_s", verify.motion_time_s},
                          {"setpoints", verify.rows},
                          {"period_s", dt},
                          {"worst_ratio", verify.worst_ratio},
                          {"worst", verify.worst},
                          {"passed", verify.Passed()},
                          {"passes", in.passes},
                          {"compute_s", in.compute_s}};
  ordered_json axis_ratios = ordered_json::array();
  for (const auto& a : verify.axes) {
    axis_ratios.push_back(
        {{"name", a.name}, {"v_ratio", a.v_ratio}, {"a_ratio", a.a_ratio}, {"j_ratio", a.j_ratio}});
  }
  summary["axes"] = std::move(axis_ratios);
  data["summary"] = std::move(summary);

  // The path: every stride-th point (a 3D line has no peaks to keep), the last one too.
  const std::size_t stride = std::max<std::size_t>(1, (n + kPathPoints - 1) / kPathPoints);
  ordered_json px = ordered_json::array(), py = ordered_json::array(), pz = ordered_json::array(),
               pf = ordered_json::array();
  for (std::size_t k = 0; k < n; k = (k + stride < n || k == n - 1) ? k + stride : n - 1) {
    px.push_back(poses[k].tip.x());
    py.push_back(poses[k].tip.y());
    pz.push_back(poses[k].tip.z());
    pf.push_back(feed[k]);
    if (k == n - 1) break;
  }
  data["path"] = {
      {"x", std::move(px)}, {"y", std::move(py)}, {"z", std::move(pz)}, {"feed", std::move(pf)}};
  const bool five_axis =
      std::any_of(axes.begin(), axes.end(), [](const Axis& a) { return a.rotary; });
  // The path's box, for the tool axis' length and the part of the face drawn.
  Eigen::Vector3d box_lo = poses[0].tip, box_hi = poses[0].tip;
  for (const auto& p : poses) {
    box_lo = box_lo.cwiseMin(p.tip);
    box_hi = box_hi.cwiseMax(p.tip);
  }
  const double extent = (box_hi - box_lo).norm();
  if (five_axis) {
    // Tool-axis segments at intervals, as long as a tenth of the path's extent.
    const double length = std::max(1.0, 0.1 * extent);
    ordered_json ax = ordered_json::array(), ay = ordered_json::array(), az = ordered_json::array();
    const std::size_t every = std::max<std::size_t>(1, n / kAxisSegments);
    for (std::size_t k = 0; k < n; k += every) {
      const Eigen::Vector3d top = poses[k].tip + length * poses[k].axis;
      for (const Eigen::Vector3d& p : {poses[k].tip, top}) {
        ax.push_back(p.x());
        ay.push_back(p.y());
        az.push_back(p.z());
      }
      ax.push_back(nullptr);
      ay.push_back(nullptr);
      az.push_back(nullptr);
    }
    data["path"]["axis"] = {{"x", std::move(ax)}, {"y", std::move(ay)}, {"z", std::move(az)}};
  }
  if (in.surface) {
    // The face around the path: its triangles cut to a margin around the path's box (a short pass
    // on a large face stays visible, and the cut is a straight edge), to the micron (a display
    // needs no more). Vertices that round to the same micron are one, so the shading stays smooth.
    const double margin = std::max(kSurfaceMarginMm, kSurfaceMarginFraction * extent);
    const Eigen::Vector3d lo = box_lo.array() - margin, hi = box_hi.array() + margin;
    const auto& vertices = in.surface->vertices;
    std::map<std::array<long long, 3>, int> index;
    ordered_json x = ordered_json::array(), y = ordered_json::array(), z = ordered_json::array(),
                 i = ordered_json::array(), j = ordered_json::array(), k = ordered_json::array();
    const auto vertex = [&](const Eigen::Vector3d& p) {
      const std::array<long long, 3> key{std::llround(p.x() * 1e3), std::llround(p.y() * 1e3),
                                         std::llround(p.z() * 1e3)};
      const auto [at, added] = index.emplace(key, static_cast<int>(x.size()));
      if (added) {
        x.push_back(static_cast<double>(key[0]) / 1e3);
        y.push_back(static_cast<double>(key[1]) / 1e3);
        z.push_back(static_cast<double>(key[2]) / 1e3);
      }
      return at->second;
    };
    for (const auto& t : in.surface->triangles) {
      std::vector<Eigen::Vector3d> corners;
      for (int c : t) corners.push_back(vertices[static_cast<std::size_t>(c)]);
      const auto polygon = ClipToBox(std::move(corners), lo, hi);
      for (std::size_t c = 1; c + 1 < polygon.size(); ++c) {
        const int a = vertex(polygon[0]), b = vertex(polygon[c]), d = vertex(polygon[c + 1]);
        if (a == b || b == d || a == d) continue;  // a sliver under a micron
        i.push_back(a);
        j.push_back(b);
        k.push_back(d);
      }
    }
    // Its outline (the edges of one triangle only), for the view from above.
    std::map<std::pair<int, int>, int> edges;
    for (std::size_t t = 0; t < i.size(); ++t) {
      const int c[3] = {i[t].get<int>(), j[t].get<int>(), k[t].get<int>()};
      for (int e = 0; e < 3; ++e) {
        ++edges[std::minmax(c[e], c[(e + 1) % 3])];
      }
    }
    ordered_json ox = ordered_json::array(), oy = ordered_json::array();
    for (const auto& [edge, count] : edges) {
      if (count != 1) continue;
      for (int v : {edge.first, edge.second}) {
        ox.push_back(x[static_cast<std::size_t>(v)]);
        oy.push_back(y[static_cast<std::size_t>(v)]);
      }
      ox.push_back(nullptr);
      oy.push_back(nullptr);
    }
    data["surface"] = {{"x", std::move(x)},
                       {"y", std::move(y)},
                       {"z", std::move(z)},
                       {"i", std::move(i)},
                       {"j", std::move(j)},
                       {"k", std::move(k)},
                       {"outline", {{"x", std::move(ox)}, {"y", std::move(oy)}}}};
  }
  if (in.compare) {
    ordered_json rows = ordered_json::array(), feeds = ordered_json::array(),
                 header = ordered_json::array();
    for (const auto& cell : CompareHeader()) header.push_back(Micro(cell));
    std::vector<std::string> planners;
    for (const auto& v : in.compare->variants) {
      ordered_json cells = ordered_json::array();
      for (const auto& cell : CompareCells(v)) cells.push_back(Micro(cell));
      rows.push_back(std::move(cells));
      // The variant the report shows in full has its feed already.
      ordered_json series =
          Series(v.table.t, &v.table == in.table ? feed : Tip(machine, v.table, dt).feed);
      const bool exact = v.kind == VariantResult::Kind::kExact;
      series["name"] = Micro(VariantLabel(v));
      series["variant"] = Micro(v.name);
      series["planner"] = interp::PlannerName(v.planner);
      series["exact"] = exact;
      series["time_s"] = v.motion_time_s;
      series["pass_time_s"] = v.pass_time_s;
      series["motion_dev_um"] = v.motion_deviation_mm * 1e3;
      series["export_dev_um"] = exact ? ordered_json() : ordered_json(v.export_deviation_mm * 1e3);
      feeds.push_back(std::move(series));
      const std::string planner = interp::PlannerName(v.planner);
      if (std::find(planners.begin(), planners.end(), planner) == planners.end()) {
        planners.push_back(planner);
      }
    }
    data["compare"] = {{"header", std::move(header)},
                       {"rows", std::move(rows)},
                       {"notes", in.compare->notes},
                       {"feeds", std::move(feeds)},
                       {"shown", Micro(in.shown)}};
    // The job names one planner; the comparison ran each of `planners`.
    if (planners.size() > 1) {
      for (auto& fact : data["about"]) {
        if (fact[0] == "interpolator") {
          fact[1] = fmt::format("VPOp, {} planners (each variant with each; below in full: {})",
                                fmt::join(planners, " and "), Micro(in.shown));
        }
      }
    }
  }
  std::vector<std::size_t> all_rows(n);
  for (std::size_t r = 0; r < n; ++r) all_rows[r] = r;
  data["feed"] = Series(table.t, feed);
  data["limiters"] = LimiterBand(in, all_rows, table.t);
  // Surface jobs: the feed against the arc length along the passes, the links left out.
  bool passes_fit = !in.pass_rows.empty();
  for (const auto& [first, end] : in.pass_rows) {
    passes_fit = passes_fit && first >= 0 && first < end && static_cast<std::size_t>(end) <= n;
  }
  if (passes_fit) {
    std::vector<std::size_t> rows;
    std::vector<double> s, f;
    ordered_json spans = ordered_json::array();
    double along = 0.0, pass_time = 0.0;
    for (const auto& [first, end] : in.pass_rows) {
      const double s0 = along;
      for (auto r = static_cast<std::size_t>(first); r < static_cast<std::size_t>(end); ++r) {
        if (r > static_cast<std::size_t>(first)) along += (poses[r].tip - poses[r - 1].tip).norm();
        rows.push_back(r);
        s.push_back(along);
        f.push_back(feed[r]);
      }
      const double t0 = table.t[static_cast<std::size_t>(first)],
                   t1 = table.t[static_cast<std::size_t>(end - 1)];
      pass_time += t1 - t0;
      spans.push_back({{"s0", s0}, {"s1", along}, {"t0", t0}, {"t1", t1}});
    }
    ordered_json xs = ordered_json::array(), ys = ordered_json::array();
    for (std::size_t i : DecimateMinMax(f, kReportPoints)) {
      xs.push_back(s[i]);
      ys.push_back(f[i]);
    }
    const double total = verify.motion_time_s;
    data["pass_feed"] = {{"s", std::move(xs)},
                         {"y", std::move(ys)},
                         {"passes", std::move(spans)},
                         {"limiters", LimiterBand(in, rows, s)},
                         {"link_time_s", std::max(0.0, total - pass_time)}};
  }

  // Per axis: how close each derivative comes to its limit (the envelope of |value| / limit in
  // windows, and the share of periods at the limit), and the values themselves.
  const std::size_t width = WindowRows(n);
  ordered_json axis_data = ordered_json::array();
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Axis& a = axes[i];
    const double scale = a.rotary ? kDeg : 1.0;
    const auto& x = table.columns[i];
    const auto v = Derivative(x, dt), acc = Derivative(v, dt), j = Derivative(acc, dt);
    const Usage uv = UsageOf(v, a.vmax * scale), ua = UsageOf(acc, a.amax * scale),
                uj = UsageOf(j, a.jmax * scale);
    axis_data.push_back({{"name", a.name},
                         {"unit", a.rotary ? "deg" : "mm"},
                         {"vmax", a.vmax * scale},
                         {"amax", a.amax * scale},
                         {"jmax", a.jmax * scale},
                         {"usage",
                          {{"velocity", Windows(table.t, uv.percent, width, false)},
                           {"acceleration", Windows(table.t, ua.percent, width, false)},
                           {"jerk", Windows(table.t, uj.percent, width, false)}}},
                         {"at_limit", {uv.at_limit, ua.at_limit, uj.at_limit}},
                         {"position", Series(table.t, x)},
                         {"velocity", Series(table.t, v)},
                         {"acceleration", Series(table.t, acc)},
                         {"jerk", Windows(table.t, j, width, true)}});
  }
  data["axes"] = std::move(axis_data);

  std::string page = kPage;
  ReplaceOnce(page, "@TITLE@", HtmlEscape(in.title));
  for (int k = 0; k < 2; ++k) ReplaceOnce(page, "@WINDOW@", std::to_string(width));
  ReplaceOnce(page, "@AT_LIMIT@", fmt::format("{:g}", 100.0 * kAtLimit));
  ReplaceOnce(page, "@DATA@", ScriptSafe(data.dump()));
  ReplaceOnce(page, "@PLOTLY@", ScriptSafe(plotly_js));  // last: the library is large
  return page;
}

std::vector<ReportFact> JobFacts(const Job& job, const Machine& machine) {
  std::vector<ReportFact> facts{
      {"job", job.file}, {"machine", fmt::format("{} ({})", machine.Name(), job.machine_file)}};
  const auto point = [](const Eigen::Vector3d& p) {
    return fmt::format("({:.6g}, {:.6g}, {:.6g})", p.x(), p.y(), p.z());
  };
  if (job.surface) {
    const SurfaceSpec& s = *job.surface;
    facts.push_back({"part", s.step_file});
    facts.push_back({s.faces.size() == 1 ? "face" : "faces", FaceRefsText(s)});
    facts.push_back({"tool", s.tool.Describe()});
    facts.push_back({"orientation", s.orientation.Describe()});
    facts.push_back({"strategy", strategies::StrategySpec::KindName(s.strategy.kind)});
  } else if (job.path.kind == PathSpec::Kind::kGcode) {
    facts.push_back({"part", "G-code program " + job.path.gcode_file});
  } else if (job.path.kind == PathSpec::Kind::kCurve) {
    facts.push_back({"part", "curve " + job.path.curve_file});
  } else {
    facts.push_back(
        {"part", fmt::format("line from {} to {} mm", point(job.path.from), point(job.path.to))});
  }
  std::string interpolator = InterpolatorName(job.interpolator);
  if (job.interpolator == InterpolatorKind::kVpop) {
    interpolator += fmt::format(", {} planner", interp::PlannerName(job.vpop.planner));
  }
  facts.push_back({"interpolator", std::move(interpolator)});
  facts.push_back({"feed", fmt::format("{:.6g} mm/min, period {:.6g} ms", job.vpop.feed_mm_s * 60.0,
                                       job.vpop.period_s * 1e3)});
  return facts;
}

// Where plotly.js is: $DTIS_PLOTLY_JS; else next to an installed dtis (PREFIX/bin/dtis reads
// PREFIX/share/dtis/plotly.min.js); else the copy scripts/bootstrap put in the source tree.
std::string PlotlyPath() {
  if (const char* env = std::getenv("DTIS_PLOTLY_JS"); env && *env) return env;
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed =
        exe.parent_path() / DTIS_DATA_FROM_BIN / "plotly.min.js";
    if (std::filesystem::is_regular_file(installed, ec)) return installed.lexically_normal();
  }
  return DTIS_PLOTLY_JS;
}

std::string LoadPlotly() {
  const std::string path = PlotlyPath();
  std::optional<std::string> plotly = ReadFileText(path);
  if (!plotly || plotly->empty()) {
    throw Error(
        "cannot read plotly.js for the HTML report from '{}'; run scripts/bootstrap (npm ci in "
        "tools/report) or set DTIS_PLOTLY_JS to a plotly.min.js",
        path.empty() ? "(no path built in)" : path);
  }
  return std::move(*plotly);
}

}  // namespace dtis::io
