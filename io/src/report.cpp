#include "dtis/io/report.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
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

// The constraint that decided each period, as points (t, label): every label that occurs in a
// bucket once, at its first period there.
ordered_json LimiterBand(const ReportInput& in) {
  ordered_json xs = ordered_json::array(), ys = ordered_json::array();
  const auto& t = in.table->t;
  const std::size_t n = std::min(in.limiters.size(), t.size());
  const std::size_t buckets = kReportPoints / 2;
  const std::size_t width = std::max<std::size_t>(1, (n + buckets - 1) / buckets);
  for (std::size_t b = 0; b < n; b += width) {
    std::vector<std::string> seen;
    for (std::size_t i = b; i < std::min(n, b + width); ++i) {
      std::string label = LimiterLabel(in.limiters[i], *in.machine);
      if (std::find(seen.begin(), seen.end(), label) != seen.end()) continue;
      xs.push_back(t[i]);
      ys.push_back(label);
      seen.push_back(std::move(label));
    }
  }
  return {{"t", std::move(xs)}, {"label", std::move(ys)}};
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
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.3em; } h2 { font-size: 1.1em; margin-top: 1.5em; }
table { border-collapse: collapse; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f3f3f3; } td:first-child, th:first-child { text-align: left; }
#about td { text-align: left; } #about td:first-child { color: #555; }
.fail { color: #b00; font-weight: bold; } .pass { color: #070; font-weight: bold; }
.plot { width: 100%; }
</style>
<script>@PLOTLY@</script>
</head><body data-report-status="loading" data-console-errors="0">
<h1>dtis report: <span id="title"></span></h1>
<table id="about"></table>
<div id="compare-section" hidden>
<h2>Comparison: the same passes from exports and on the exact surface</h2>
<table id="compare"></table><ul id="compare-notes"></ul>
<h2>Feed against time, every variant</h2><div id="compare-feed" class="plot" data-figure="compare-feed" style="height:520px"></div>
<h2 id="shown"></h2>
</div>
<table id="summary"></table>
<div id="unreachable-section" hidden><h2>Left out where the tool does not fit</h2>
<pre id="unreachable"></pre></div>
<h2 id="path-title">Tool path, coloured by feed</h2><div id="path" class="plot" data-figure="path" style="height:600px"></div>
<h2>Feed against time, and the constraint that decided each period</h2>
<div id="feed" class="plot" data-figure="feed" style="height:520px"></div>
<h2>Axes against their limits</h2><div id="axes"></div>
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
function summary() {
  const s = DATA.summary, t = document.getElementById('summary');
  document.getElementById('title').textContent = DATA.title;
  for (const [k, v] of DATA.about) document.getElementById('about').appendChild(row([k, v]));
  const kv = [['motion time', s.motion_time_s.toFixed(6) + ' s'], ['setpoints', s.setpoints + ' at ' + (s.period_s * 1e3) + ' ms'],
              ['worst ratio', s.worst_ratio.toFixed(9) + ' (' + s.worst + ')'], ['verifier', s.passed ? 'PASS' : 'FAIL']];
  if (s.passes > 0) kv.push(['passes', String(s.passes)]);
  if (s.compute_s >= 0) kv.push(['compute time', s.compute_s.toFixed(3) + ' s']);
  for (const [k, v] of kv) { const r = row([k, v]); if (k === 'verifier') r.lastChild.className = s.passed ? 'pass' : 'fail'; t.appendChild(r); }
  t.appendChild(row(['axis', '|v| / limit', '|a| / limit', '|j| / limit'], true));
  for (const a of s.axes) t.appendChild(row([a.name, a.v_ratio.toFixed(6), a.a_ratio.toFixed(6), a.j_ratio.toFixed(6)]));
  if (DATA.unreachable) {
    document.getElementById('unreachable').textContent = DATA.unreachable;
    document.getElementById('unreachable-section').hidden = false;
  }
}
function compareSection() {
  const c = DATA.compare;
  if (!c) return [];
  document.getElementById('compare-section').hidden = false;
  const t = document.getElementById('compare');
  t.appendChild(row(c.header, true));
  for (const r of c.rows) t.appendChild(row(r));
  for (const n of c.notes) { const li = document.createElement('li'); li.textContent = 'note: ' + n; document.getElementById('compare-notes').appendChild(li); }
  document.getElementById('shown').textContent = 'The run in full: ' + c.shown;
  const traces = c.feeds.map(f => ({ type: 'scatter', mode: 'lines', name: f.name, x: f.t, y: f.y }));
  if (DATA.programmed_feed > 0) {
    const t1 = Math.max(...c.feeds.map(f => f.t[f.t.length - 1]));
    traces.push({ type: 'scatter', mode: 'lines', name: 'programmed feed', x: [0, t1], y: [DATA.programmed_feed, DATA.programmed_feed],
                  line: { color: '#d62728', dash: 'dash' } });
  }
  return [Plotly.newPlot('compare-feed', traces, { margin: { t: 40 }, xaxis: { title: { text: 't (s)' } },
    yaxis: { title: { text: 'feed (mm/min)' } }, legend: { orientation: 'h', x: 0, y: 1.02, yanchor: 'bottom' } },
    { responsive: true })];
}
// The 3-D view needs WebGL; without it (a locked-down browser, a remote desktop) the path is drawn
// from above in SVG, coloured by feed the same way.
function hasWebGL() {
  try { const c = document.createElement('canvas'); return !!(c.getContext('webgl') || c.getContext('experimental-webgl')); }
  catch (e) { return false; }
}
function pathTopView() {
  const p = DATA.path, every = Math.max(1, Math.ceil(p.x.length / 4000)), pick = a => a.filter((_, i) => i % every === 0);
  document.getElementById('path-title').textContent = 'Tool path from above, coloured by feed (the 3-D view needs WebGL, which this browser does not offer)';
  const trace = { type: 'scatter', mode: 'markers', name: 'tool tip', x: pick(p.x), y: pick(p.y),
    marker: { size: 3, color: pick(p.feed), colorscale: 'Jet', cmin: 0, showscale: true, colorbar: { title: { text: 'mm/min' } } },
    hovertemplate: 'x %{x:.3f}<br>y %{y:.3f}<br>feed %{marker.color:.0f} mm/min<extra></extra>' };
  return Plotly.newPlot('path', [trace], { margin: { t: 10 }, showlegend: false, xaxis: { title: { text: 'x (mm)' } },
    yaxis: { title: { text: 'y (mm)' }, scaleanchor: 'x' } }, { responsive: true });
}
function pathPlot() {
  if (!hasWebGL()) return pathTopView();
  const p = DATA.path, traces = [];
  if (DATA.surface) { const f = DATA.surface; traces.push({ type: 'mesh3d', name: 'surface', x: f.x, y: f.y, z: f.z, i: f.i, j: f.j, k: f.k,
    color: '#b8c4d0', opacity: 0.55, flatshading: false, hoverinfo: 'skip', lighting: { ambient: 0.7, diffuse: 0.5, specular: 0.1 } }); }
  traces.push({
    type: 'scatter3d', mode: 'lines', name: 'tool tip', x: p.x, y: p.y, z: p.z,
    line: { width: 5, color: p.feed, colorscale: 'Jet', cmin: 0, showscale: true, colorbar: { title: { text: 'mm/min' } } },
    hovertemplate: 'x %{x:.3f}<br>y %{y:.3f}<br>z %{z:.3f}<br>feed %{line.color:.0f} mm/min<extra></extra>' });
  if (p.axis) traces.push({ type: 'scatter3d', mode: 'lines', name: 'tool axis', x: p.axis.x, y: p.axis.y, z: p.axis.z,
                            line: { width: 2, color: '#555' }, hoverinfo: 'skip' });
  return Plotly.newPlot('path', traces, { margin: { t: 10, l: 10, r: 10, b: 10 }, showlegend: false,
    scene: { aspectmode: 'data', camera: { eye: { x: 1.55, y: 1.55, z: 1.2 } }, xaxis: { title: { text: 'x (mm)' } }, yaxis: { title: { text: 'y (mm)' } }, zaxis: { title: { text: 'z (mm)' } } } },
    { responsive: true });
}
function feedPlot() {
  const f = DATA.feed, traces = [{ type: 'scatter', mode: 'lines', name: 'feed', x: f.t, y: f.y, line: { color: '#1f77b4' } }];
  if (DATA.programmed_feed > 0) traces.push({ type: 'scatter', mode: 'lines', name: 'programmed feed',
    x: [f.t[0], f.t[f.t.length - 1]], y: [DATA.programmed_feed, DATA.programmed_feed], line: { color: '#d62728', dash: 'dash' } });
  if (DATA.limiters.t.length) traces.push({ type: 'scatter', mode: 'markers', name: 'deciding constraint',
    x: DATA.limiters.t, y: DATA.limiters.label, yaxis: 'y2', marker: { size: 4, color: '#555' } });
  return Plotly.newPlot('feed', traces, { margin: { t: 10 }, xaxis: { title: { text: 't (s)' }, anchor: DATA.limiters.t.length ? 'y2' : 'y' },
    yaxis: { title: { text: 'feed (mm/min)' }, domain: DATA.limiters.t.length ? [0.42, 1] : [0, 1] },
    yaxis2: { domain: [0, 0.34], type: 'category', automargin: true } }, { responsive: true });
}
function axisPlot(a) {
  const div = document.createElement('div'); div.className = 'plot'; div.style.height = '760px'; div.dataset.figure = 'axis-' + a.name;
  document.getElementById('axes').appendChild(div);
  const names = ['position', 'velocity', 'acceleration', 'jerk'], units = [a.unit, a.unit + '/s', a.unit + '/s²', a.unit + '/s³'];
  const series = [a.position, a.velocity, a.acceleration, a.jerk], limits = [null, a.vmax, a.amax, a.jmax];
  const traces = [], layout = { margin: { t: 30 }, title: { text: 'axis ' + a.name, x: 0 }, showlegend: false,
    xaxis: { title: { text: 't (s)' }, anchor: 'y4' } };
  const t0 = DATA.feed.t[0], t1 = DATA.feed.t[DATA.feed.t.length - 1];
  for (let k = 0; k < 4; ++k) {
    const y = k ? 'y' + (k + 1) : 'y';
    traces.push({ type: 'scatter', mode: 'lines', name: names[k], x: series[k].t, y: series[k].y, yaxis: y, xaxis: 'x', line: { color: '#1f77b4' } });
    if (limits[k] !== null) for (const sign of [1, -1]) traces.push({ type: 'scatter', mode: 'lines', name: (sign > 0 ? '+' : '-') + 'limit',
      x: [t0, t1], y: [sign * limits[k], sign * limits[k]], yaxis: y, line: { color: '#d62728', dash: 'dash', width: 1 } });
    layout['yaxis' + (k ? k + 1 : '')] = { title: { text: names[k] + ' (' + units[k] + ')' }, domain: [0.76 - 0.25 * k, 0.98 - 0.25 * k] };
  }
  return Plotly.newPlot(div, traces, layout, { responsive: true });
}
// Static figures (dtis figures): with #figures=png,svg in the address, every plot is exported as
// an image with Plotly.toImage, base64 in a pre element of #figures that a headless browser's DOM
// dump carries out (io/src/figures.cpp reads them).
function base64(text) {
  const bytes = new TextEncoder().encode(text);
  let binary = '';
  for (let i = 0; i < bytes.length; i += 0x8000) binary += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(binary);
}
async function figures(formats, width) {
  const out = document.getElementById('figures');
  for (const div of document.querySelectorAll('[data-figure]')) {
    if (!div.data) continue;  // not plotted (no comparison)
    for (const format of formats) {
      const url = await Plotly.toImage(div, { format, width, height: div.clientHeight });
      const payload = url.slice(url.indexOf(',') + 1);
      const pre = document.createElement('pre');
      pre.className = 'figure';
      pre.dataset.name = div.dataset.figure;
      pre.dataset.format = format;
      pre.textContent = format === 'svg' ? base64(decodeURIComponent(payload)) : payload;
      out.appendChild(pre);
    }
  }
}
const wanted = new URLSearchParams(location.hash.slice(1));
summary();
Promise.all([...compareSection(), pathPlot(), feedPlot(), ...DATA.axes.map(axisPlot)]).then(async plots => {
  document.body.dataset.traces = plots.reduce((n, p) => n + p.data.length, 0);
  document.body.dataset.plots = plots.length;
  // 2-D plots drawn in SVG with every trace there, for a browser's test with WebGL on or off.
  document.body.dataset.drawn2d = plots.filter(p => p.querySelector('.cartesianlayer') &&
    p.querySelectorAll('.scatterlayer .trace').length === p.data.length).length;
  document.body.dataset.webgl = hasWebGL() ? 'yes' : 'no';
  if (wanted.has('figures')) {
    await figures(wanted.get('figures').split(','), +(wanted.get('width') || 1200));
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
    // The face around the path: triangles with a vertex within a margin of the path's box (a short
    // pass on a large face stays visible), to the micron (a display needs no more).
    const double margin = std::max(kSurfaceMarginMm, kSurfaceMarginFraction * extent);
    const Eigen::Vector3d lo = box_lo.array() - margin, hi = box_hi.array() + margin;
    const auto& vertices = in.surface->vertices;
    const auto near = [&](int v) {
      const Eigen::Vector3d& p = vertices[static_cast<std::size_t>(v)];
      return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
    };
    std::vector<int> index(vertices.size(), -1);
    ordered_json x = ordered_json::array(), y = ordered_json::array(), z = ordered_json::array(),
                 i = ordered_json::array(), j = ordered_json::array(), k = ordered_json::array();
    const auto micron = [](double mm) { return std::round(mm * 1e3) / 1e3; };
    const auto vertex = [&](int v) {
      int& at = index[static_cast<std::size_t>(v)];
      if (at < 0) {
        const Eigen::Vector3d& p = vertices[static_cast<std::size_t>(v)];
        at = static_cast<int>(x.size());
        x.push_back(micron(p.x()));
        y.push_back(micron(p.y()));
        z.push_back(micron(p.z()));
      }
      return at;
    };
    for (const auto& t : in.surface->triangles) {
      if (!near(t[0]) && !near(t[1]) && !near(t[2])) continue;
      i.push_back(vertex(t[0]));
      j.push_back(vertex(t[1]));
      k.push_back(vertex(t[2]));
    }
    data["surface"] = {{"x", std::move(x)}, {"y", std::move(y)}, {"z", std::move(z)},
                       {"i", std::move(i)}, {"j", std::move(j)}, {"k", std::move(k)}};
  }
  if (in.compare) {
    ordered_json rows = ordered_json::array(), feeds = ordered_json::array();
    for (const auto& v : in.compare->variants) {
      rows.push_back(CompareCells(v));
      // The variant the report shows in full has its feed already.
      ordered_json series =
          Series(v.table.t, &v.table == in.table ? feed : Tip(machine, v.table, dt).feed);
      series["name"] = VariantLabel(v);
      feeds.push_back(std::move(series));
    }
    data["compare"] = {{"header", CompareHeader()},
                       {"rows", std::move(rows)},
                       {"notes", in.compare->notes},
                       {"feeds", std::move(feeds)},
                       {"shown", in.shown}};
  }
  data["feed"] = Series(table.t, feed);
  data["limiters"] = LimiterBand(in);

  ordered_json axis_data = ordered_json::array();
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Axis& a = axes[i];
    const double scale = a.rotary ? kDeg : 1.0;
    const auto& x = table.columns[i];
    const auto v = Derivative(x, dt), acc = Derivative(v, dt), j = Derivative(acc, dt);
    axis_data.push_back({{"name", a.name},
                         {"unit", a.rotary ? "deg" : "mm"},
                         {"vmax", a.vmax * scale},
                         {"amax", a.amax * scale},
                         {"jmax", a.jmax * scale},
                         {"position", Series(table.t, x)},
                         {"velocity", Series(table.t, v)},
                         {"acceleration", Series(table.t, acc)},
                         {"jerk", Series(table.t, j)}});
  }
  data["axes"] = std::move(axis_data);

  std::string page = kPage;
  ReplaceOnce(page, "@TITLE@", HtmlEscape(in.title));
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
