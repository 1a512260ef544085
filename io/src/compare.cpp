#include "dtis/io/compare.hpp"

#include <fmt/format.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <numbers>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/geometry/path_fit.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/exports.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::io {
namespace {

using geometry::AngleDeg;
using geometry::PathSamples;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// The smoothed-axis variant's name: "DTIS (axis within 0.1 deg)".
std::string SmoothedName(double tol_deg) {
  return fmt::format("DTIS (axis within {:g} deg)", tol_deg);
}

// "10 um", "0.5 um": tolerances as the paper names them.
std::string Microns(double mm) { return fmt::format("{:g} um", mm * 1e3); }
std::string FileMicrons(double mm) {
  std::string s = fmt::format("{:g}um", mm * 1e3);
  std::replace(s.begin(), s.end(), '.', 'p');
  return s;
}

// Per pass, in parallel (each pass's PathSource is used by one thread at a time).
template <class F>
void ForEachPass(int passes, F f) {
  tbb::parallel_for(0, passes, [&f](int k) { f(static_cast<std::size_t>(k)); });
}

// The rows [first, end) of segment `seg` of a program.
std::pair<long, long> SegmentRows(const interp::ProgramResult& program, std::size_t seg) {
  const long end = seg + 1 < program.first_row.size() ? program.first_row[seg + 1]
                                                      : static_cast<long>(program.setpoints.size());
  return {program.first_row[seg], end};
}

// The share of pass periods each axis constraint decided, largest first: "Z jerk 18.5%, ...".
std::string LimitingAxes(const interp::ProgramResult& program, const std::vector<int>& pass_of,
                         const Machine& machine) {
  std::map<std::pair<int, int>, long> count;
  long total = 0;
  for (std::size_t seg = 0; seg < pass_of.size(); ++seg) {
    if (pass_of[seg] < 0) continue;
    const auto [first, end] = SegmentRows(program, seg);
    for (long r = first; r < end; ++r) {
      const interp::LimiterId& l = program.setpoints[static_cast<std::size_t>(r)].limiter;
      ++total;
      if (l.axis >= 0) ++count[{l.axis, static_cast<int>(l.kind)}];
    }
  }
  std::vector<std::pair<long, std::pair<int, int>>> sorted;
  for (const auto& [key, n] : count) sorted.push_back({n, key});
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::string out;
  for (std::size_t i = 0; i < sorted.size() && i < 3; ++i) {
    const double share = 100.0 * static_cast<double>(sorted[i].first) / static_cast<double>(total);
    if (share < 0.5) break;
    std::string kind = interp::LimiterName(static_cast<interp::Limiter>(sorted[i].second.second));
    if (kind.rfind("axis_", 0) == 0) kind = kind.substr(5);
    out += fmt::format("{}{} {} {:.1f}%", out.empty() ? "" : ", ",
                       machine.Axes()[static_cast<std::size_t>(sorted[i].second.first)].name, kind,
                       share);
  }
  return out.empty() ? "tangential feed" : out;
}

// The largest distance of the planned tip positions on the passes to the exact path (`tip`), and
// the largest angle of the planned tool axis to the rule's axis (`axis`) at the nearest point of
// its exact path. Both are the exact passes, except for a smoothed axis (ExactVariant with a
// tolerance), whose tip is measured on its own pass and whose axis against the rule's.
struct ExactPaths {
  const std::vector<const PathSource*>& passes;
  const std::vector<PathSamples>& samples;
};
void MotionDeviation(const interp::ProgramResult& program, const std::vector<int>& pass_of,
                     const ExactPaths& tip, const ExactPaths& axis, const Machine& machine,
                     VariantResult* v) {
  const std::size_t n = tip.passes.size();
  std::vector<std::size_t> segment_of_pass(n, pass_of.size());
  for (std::size_t seg = 0; seg < pass_of.size(); ++seg) {
    if (pass_of[seg] >= 0) segment_of_pass[static_cast<std::size_t>(pass_of[seg])] = seg;
  }
  const bool same = &tip.passes == &axis.passes;
  std::vector<double> dev(n, 0.0), ang(n, 0.0);
  ForEachPass(static_cast<int>(n), [&](std::size_t k) {
    const std::size_t seg = segment_of_pass[k];
    if (seg == pass_of.size()) return;
    const geometry::PathProjector on_tip(*tip.passes[k], tip.samples[k]);
    const geometry::PathProjector on_axis(*axis.passes[k], axis.samples[k]);
    const auto [first, end] = SegmentRows(program, seg);
    std::size_t hint = 0, axis_hint = 0;
    for (long r = first; r < end; ++r) {
      const Pose pose = machine.Forward(program.setpoints[static_cast<std::size_t>(r)].q);
      const auto foot = on_tip.Project(pose.tip, &hint);
      dev[k] = std::max(dev[k], foot.distance);
      const Eigen::Vector3d rule =
          same ? foot.pose.axis : on_axis.Project(pose.tip, &axis_hint).pose.axis;
      ang[k] = std::max(ang[k], AngleDeg(pose.axis, rule));
    }
  });
  v->motion_deviation_mm = *std::max_element(dev.begin(), dev.end());
  v->motion_axis_deviation_deg = *std::max_element(ang.begin(), ang.end());
}

void Finish(const interp::ProgramResult& program, const std::vector<int>& pass_of,
            const Machine& machine, double period_s, VariantResult* v) {
  TableSink sink(machine, period_s);
  for (const auto& sp : program.setpoints) sink.Accept(sp);
  v->verify = interp::Verify(sink.Table(), machine);
  v->table = sink.Table();
  v->limiters = sink.Limiters();
  v->motion_time_s = v->verify.motion_time_s;
  v->pass_time_s = 0.0;
  for (std::size_t k = 0; k < pass_of.size(); ++k) {
    if (pass_of[k] >= 0) v->pass_time_s += program.segments[k].motion_time_s;
  }
  v->limiting = LimitingAxes(program, pass_of, machine);
}

void WriteText(const std::string& path, const std::string& text, VariantResult* v) {
  WriteFileAtomically(path, text);
  v->files.push_back(path);
}

struct Context {
  const Job& job;
  const CompareOptions& options;
  const Machine& machine;
  const SurfaceSetup& setup;
  std::vector<const PathSource*> exact;
  std::vector<PathSamples> samples;
  // Per pass, the exact pose halfway between samples i and i + 1: points the exports were not
  // made from, where their deviation is measured.
  std::vector<std::vector<Pose>> between;
  RunOptions run;
  std::string stem;  // exports_dir/job name
};

// How an export links the passes: as the exact run does.
LinkSpec LinksOf(const SurfaceSetup& setup) {
  LinkSpec links{0.0, setup.clearance_mm, setup.link_heights.get(), {}};
  for (const auto& pass : setup.passes.passes)
    links.straight.push_back(pass->RidesOverFromPrevious());
  return links;
}

// An export's tolerances: `tol` on the tip, the job's on the tool axis.
geometry::ExportTolerance ToleranceOf(const CompareSpec& spec, double tol) {
  return {tol, spec.orientation_tol_deg, spec.corners.top_height_mm};
}

VariantResult G1Variant(const Context& c, double tol) {
  const auto start = Clock::now();
  VariantResult v;
  v.kind = VariantResult::Kind::kG1;
  v.name = "G1 " + Microns(tol);
  v.tolerance_mm = tol;
  const CompareSpec& spec = c.job.compare;
  const std::size_t n = c.exact.size();
  const geometry::ExportTolerance et = ToleranceOf(spec, tol);
  std::vector<std::vector<std::size_t>> vertices(n);
  std::vector<std::vector<Pose>> poses(n);
  ForEachPass(static_cast<int>(n), [&](std::size_t k) {
    vertices[k] = geometry::ChordalVertices(c.samples[k], et);
    for (std::size_t i : vertices[k])
      poses[k].push_back({c.samples[k].tip[i], c.samples[k].axis[i]});
  });
  const std::string file =
      c.stem.empty() ? c.job.name + ".ngc" : fmt::format("{}_g1_{}.ngc", c.stem, FileMicrons(tol));
  const double feed_mm_min = c.setup.pass_options.feed_mm_s * 60.0;
  const GcodeExport g =
      ExportG1(poses, c.machine, feed_mm_min, LinksOf(c.setup),
               {fmt::format("dtis G1 export of job {}: {} passes, chordal tolerance {} mm",
                            c.job.name, n, tol),
                fmt::format("machine {}: X Y Z = tool tip (mm), rotary words = machine axes (deg)",
                            c.machine.Name())},
               file);
  for (const auto& p : vertices) v.blocks += static_cast<long>(p.size()) - 1;
  if (!c.stem.empty()) WriteText(file, g.text, &v);

  // Plan the program as written: corner smoothing, links as rapids at the link feed.
  GcodeOptions go;
  go.corners = spec.corners;
  go.rapid_feed_mm_s = c.setup.link_options.feed_mm_s;
  go.start_at_first_move = true;  // at the first pass, as the exact variant
  const GcodePlan plan = BuildGcodePlan(g.program, c.machine, c.job.vpop, go);
  interp::ProgramOptions po;
  po.threads = c.options.threads;
  interp::ProgramResult program;
  try {
    program = interp::PlanProgram(plan.segments, c.machine, po);
  } catch (const Error& e) {
    throw Error("{}: {}: {}", c.job.file, v.name, e.what());
  }
  std::vector<int> pass_of;
  int next = 0;
  for (std::size_t k = 0; k < plan.segments.size(); ++k)
    pass_of.push_back(plan.rapid[k] ? -1 : next++);
  if (next != static_cast<int>(n)) {
    throw Error("{}: {}: the program has {} contours for {} passes", c.job.file, v.name, next, n);
  }
  Finish(program, pass_of, c.machine, c.job.vpop.period_s, &v);

  // The export's deviation, at the exact points between samples (to their chord) and at the chords'
  // quarter points (to the exact path). The polyline is the program's, as rounded in the text.
  std::vector<std::vector<Pose>> written;
  const GcodeToolAxis axis_of(g.program, c.machine);
  const auto& moves = g.program.moves;
  for (std::size_t m = 1; m < moves.size(); ++m) {
    if (moves[m].kind != GcodeMove::Kind::kLinear) continue;
    if (moves[m - 1].kind != GcodeMove::Kind::kLinear) {
      written.emplace_back();
      written.back().push_back({moves[m - 1].to, axis_of(moves[m - 1])});
    }
    written.back().push_back({moves[m].to, axis_of(moves[m])});
  }
  std::vector<double> dev(n, 0.0), ang(n, 0.0);
  ForEachPass(static_cast<int>(n), [&](std::size_t k) {
    const PathSamples& s = c.samples[k];
    const auto& w = written[k];
    const auto& vx = vertices[k];
    // Tip and top interpolated alike: top - tip = h ((1 - t) axis_j + t axis_j+1).
    const auto axis_at = [&](std::size_t j, double t) -> Eigen::Vector3d {
      return (1 - t) * w[j].axis + t * w[j + 1].axis;
    };
    std::size_t j = 0;
    for (std::size_t i = 0; i + 1 < s.Size(); ++i) {
      while (j + 2 < vx.size() && vx[j + 1] <= i) ++j;
      const Pose& e = c.between[k][i];
      double t = 0.0;
      dev[k] = std::max(dev[k], geometry::DistanceToSegment(e.tip, w[j].tip, w[j + 1].tip, &t));
      ang[k] = std::max(ang[k], AngleDeg(axis_at(j, t), e.axis));
    }
    const geometry::PathProjector projector(*c.exact[k], s);
    std::size_t hint = 0;
    for (std::size_t b = 0; b + 1 < w.size(); ++b) {
      for (double t : {0.25, 0.5, 0.75}) {
        const Eigen::Vector3d x = (1 - t) * w[b].tip + t * w[b + 1].tip;
        const auto foot = projector.Project(x, &hint);
        dev[k] = std::max(dev[k], foot.distance);
        ang[k] = std::max(ang[k], AngleDeg(axis_at(b, t), foot.pose.axis));
      }
    }
  });
  v.export_deviation_mm = *std::max_element(dev.begin(), dev.end());
  v.export_axis_deviation_deg = *std::max_element(ang.begin(), ang.end());
  MotionDeviation(program, pass_of, {c.exact, c.samples}, {c.exact, c.samples}, c.machine, &v);
  v.compute_s = Seconds(start);
  return v;
}

VariantResult BSplineVariant(const Context& c, double tol, std::vector<std::string>* notes) {
  const auto start = Clock::now();
  VariantResult v;
  v.kind = VariantResult::Kind::kBSpline;
  v.name = "B-spline " + Microns(tol);
  v.tolerance_mm = tol;
  const std::size_t n = c.exact.size();
  geometry::BSplineFitOptions fo;
  fo.tolerance = ToleranceOf(c.job.compare, tol);
  std::vector<std::unique_ptr<geometry::BSplineFit>> fits(n);
  std::vector<std::unique_ptr<geometry::CurvePath>> paths(n);
  ForEachPass(static_cast<int>(n), [&](std::size_t k) {
    const std::string what = fmt::format("{}: {}, pass {}", c.job.file, v.name, k + 1);
    fits[k] =
        std::make_unique<geometry::BSplineFit>(geometry::FitCubicBSpline(c.samples[k], fo, what));
    const auto& f = *fits[k];
    paths[k] = f.top ? std::make_unique<geometry::CurvePath>(f.bottom, *f.top, c.job.arc_length)
                     : std::make_unique<geometry::CurvePath>(f.bottom, c.samples[k].axis.front(),
                                                             c.job.arc_length);
  });
  std::vector<SplinePass> spline_passes;
  for (std::size_t k = 0; k < n; ++k) {
    v.blocks += static_cast<long>(fits[k]->bottom.Poles().size());
    spline_passes.push_back(
        {&fits[k]->bottom, fits[k]->top ? &*fits[k]->top : nullptr, c.samples[k].axis.front()});
  }
  const double feed_mm_min = c.setup.pass_options.feed_mm_s * 60.0;
  const LinkSpec links = LinksOf(c.setup);
  if (!c.stem.empty()) {
    const std::string base = fmt::format("{}_bspline_{}", c.stem, FileMicrons(tol));
    for (std::size_t k = 0; k < n; ++k) {
      const std::string pair =
          spline_passes[k].top
              ? fmt::format(" (5-axis bottom/top pair, top curve {:g} mm up the tool axis)",
                            fo.tolerance.top_height_mm)
              : "";
      WriteText(fmt::format("{}_pass{:02}.toml", base, k + 1),
                FormatCurveFile(spline_passes[k],
                                {fmt::format("dtis B-spline export of job {}, pass {} of {}, "
                                             "tolerance {} mm{}",
                                             c.job.name, k + 1, n, tol, pair)}),
                &v);
    }
    WriteText(base + ".mpf",
              FormatSiemensBspline(
                  spline_passes, feed_mm_min, links,
                  {fmt::format("dtis B-spline export of job {}: {} passes, tolerance {} mm",
                               c.job.name, n, tol),
                   "Siemens 840D-style BSPLINE program (syntax per the SINUMERIK programming "
                   "manual; not run on a controller by dtis)"}),
              &v);
    // LinuxCNC's G5.2 is XY only, with uniform knots: a separate fit, for planar passes.
    if (PlanarXY(spline_passes, 1e-9)) {
      geometry::BSplineFitOptions uo = fo;
      uo.uniform_knots = true;
      std::vector<std::unique_ptr<geometry::BSplineFit>> uniform(n);
      ForEachPass(static_cast<int>(n), [&](std::size_t k) {
        uniform[k] = std::make_unique<geometry::BSplineFit>(geometry::FitCubicBSpline(
            c.samples[k], uo,
            fmt::format("{}: {} (uniform knots), pass {}", c.job.file, v.name, k + 1)));
      });
      std::vector<SplinePass> up;
      for (std::size_t k = 0; k < n; ++k)
        up.push_back({&uniform[k]->bottom, nullptr, Eigen::Vector3d::UnitZ()});
      WriteText(base + "_linuxcnc.ngc",
                FormatLinuxcncNurbs(up, feed_mm_min, links,
                                    {fmt::format("dtis B-spline export of job {}: {} passes, "
                                                 "tolerance {} mm, uniform knots (G5.2)",
                                                 c.job.name, n, tol)}),
                &v);
    } else {
      notes->push_back(
          fmt::format("{}: no LinuxCNC G5.2 program: G5.2 is XY only and these passes move in Z{}",
                      v.name, c.samples.front().turning_axis ? " and turn the tool axis" : ""));
    }
  }

  std::vector<const PathSource*> ptrs;
  for (const auto& p : paths) ptrs.push_back(p.get());
  const PassProgram pp = PlanPasses(ptrs, c.setup, c.machine, c.run, c.job.file);
  Finish(pp.program, pp.pass_of_segment, c.machine, c.job.vpop.period_s, &v);
  v.pass_rows = PassRows(pp);

  // The export's deviation: exact points between samples to the curve, and curve points between
  // samples to the exact path.
  std::vector<double> dev(n, 0.0), ang(n, 0.0);
  ForEachPass(static_cast<int>(n), [&](std::size_t k) {
    const PathSamples& s = c.samples[k];
    const auto& f = *fits[k];
    const auto axis_at = [&](double u) -> Eigen::Vector3d {
      return f.top ? Eigen::Vector3d((f.top->Point(u) - f.bottom.Point(u)).normalized())
                   : s.axis.front();
    };
    const geometry::PathProjector projector(*c.exact[k], s);
    std::size_t hint = 0;
    for (std::size_t i = 0; i + 1 < s.Size(); ++i) {
      const double mid = 0.5 * (s.s[i] + s.s[i + 1]);
      const Pose& e = c.between[k][i];
      const double u = geometry::ClosestOnCurve(f.bottom, e.tip, mid);
      dev[k] = std::max(dev[k], (f.bottom.Point(u) - e.tip).norm());
      ang[k] = std::max(ang[k], AngleDeg(axis_at(u), e.axis));
      const auto foot = projector.Project(f.bottom.Point(mid), &hint);
      dev[k] = std::max(dev[k], foot.distance);
      ang[k] = std::max(ang[k], AngleDeg(axis_at(mid), foot.pose.axis));
    }
  });
  v.export_deviation_mm = *std::max_element(dev.begin(), dev.end());
  v.export_axis_deviation_deg = *std::max_element(ang.begin(), ang.end());
  MotionDeviation(pp.program, pp.pass_of_segment, {c.exact, c.samples}, {c.exact, c.samples},
                  c.machine, &v);
  v.compute_s = Seconds(start);
  return v;
}

// The exact surface planned on `passes` and their links (`setup`): with the rule's axis when
// `tol_deg` is 0, else with the axis smoothed within it ([orientation] axis_tolerance_deg). The tip
// is measured on its own exact passes, the axis against the rule's (c.exact).
VariantResult ExactVariant(const Context& c, const SurfaceSetup& setup,
                           const std::vector<const PathSource*>& passes,
                           const std::vector<PathSamples>& samples, double tol_deg) {
  const auto start = Clock::now();
  VariantResult v;
  v.kind = VariantResult::Kind::kExact;
  v.name = tol_deg > 0.0 ? SmoothedName(tol_deg) : "DTIS (exact surface)";
  v.axis_tolerance_deg = tol_deg;
  const PassProgram pp = PlanPasses(passes, setup, c.machine, c.run, c.job.file);
  Finish(pp.program, pp.pass_of_segment, c.machine, c.job.vpop.period_s, &v);
  v.pass_rows = PassRows(pp);
  MotionDeviation(pp.program, pp.pass_of_segment, {passes, samples}, {c.exact, c.samples},
                  c.machine, &v);
  v.compute_s = Seconds(start);
  return v;
}

}  // namespace

CompareResult RunCompare(const Job& job, const CompareOptions& options) {
  if (!job.surface) {
    throw Error("{}: only surface jobs ([surface]) are compared with their exports", job.file);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  static_cast<std::size_t>(options.threads));
  }
  const auto machine = LoadJobMachine(job);
  const CompareSpec& spec = job.compare;
  // Each planner plans from a copy of the job and of the passes' options that names it. The
  // exports are made from the rule's axis, the papers' reference, whatever the job smooths.
  Job planned = job;
  if (planned.surface) planned.surface->orientation.axis_tolerance_rad = 0.0;
  SurfaceSetup setup = SetUpSurface(planned);
  CheckPassesInTravel(setup, *machine, job.file);
  Context c{planned, options, *machine, setup, {}, {}, {}, {}, {}};
  c.run.threads = options.threads;
  CompareResult r;
  r.job = job.name;
  r.machine = machine->Name();
  r.passes = static_cast<int>(setup.passes.passes.size());
  r.sample_step_mm = spec.sample_step_mm;
  for (const auto& p : setup.passes.passes) {
    c.exact.push_back(p.get());
    r.path_length_mm += *p->Length();
  }
  c.samples.resize(c.exact.size());
  c.between.resize(c.exact.size());
  ForEachPass(r.passes, [&](std::size_t k) {
    const PathSamples& s = c.samples[k] = geometry::SamplePath(
        *c.exact[k], spec.sample_step_mm, fmt::format("{}: pass {}", job.file, k + 1));
    for (std::size_t i = 0; i + 1 < s.Size(); ++i) {
      c.between[k].push_back(c.exact[k]->At(s.state[i], 0.5 * (s.s[i] + s.s[i + 1])).pose);
    }
  });
  if (!options.exports_dir.empty()) {
    std::filesystem::create_directories(options.exports_dir);
    c.stem = (std::filesystem::path(options.exports_dir) / job.name).string();
  }
  const auto progress = [&options](const std::string& name) {
    if (options.progress) options.progress(name);
  };
  std::vector<interp::PlannerKind> planners = options.planners;
  if (planners.empty()) planners.push_back(job.vpop.planner);
  const std::string stem = c.stem;
  // Plans a variant with every planner in turn; the exports are written once.
  const auto with_each_planner = [&](const std::string& name, const auto& variant) {
    for (std::size_t i = 0; i < planners.size(); ++i) {
      const interp::PlannerKind p = planners[i];
      planned.vpop.planner = setup.pass_options.planner = setup.link_options.planner = p;
      c.stem = i == 0 ? stem : "";
      progress(planners.size() > 1 ? fmt::format("{} ({})", name, interp::PlannerName(p)) : name);
      r.variants.push_back(variant());
      r.variants.back().planner = p;
    }
  };
  for (double tol : spec.g1_tolerances_mm) {
    with_each_planner("G1 " + Microns(tol), [&] { return G1Variant(c, tol); });
  }
  for (double tol : spec.bspline_tolerances_mm) {
    std::vector<std::string> notes;
    with_each_planner("B-spline " + Microns(tol), [&] { return BSplineVariant(c, tol, &notes); });
    for (const auto& note : notes) {
      if (std::find(r.notes.begin(), r.notes.end(), note) == r.notes.end()) r.notes.push_back(note);
    }
  }
  with_each_planner("DTIS (exact surface)",
                    [&] { return ExactVariant(c, setup, c.exact, c.samples, 0.0); });
  // A tilt_yaw axis is also smoothed within the tolerance the exports keep the axis in, like for
  // like, and within the job's own tolerance if it names another.
  if (job.surface->orientation.kind == strategies::Orientation::Kind::kTiltYaw) {
    std::vector<double> tolerances{spec.orientation_tol_deg};
    const double own = job.surface->orientation.axis_tolerance_rad * 180.0 / std::numbers::pi;
    if (own > 0.0 && std::abs(own - spec.orientation_tol_deg) > 1e-9) tolerances.push_back(own);
    for (double tol : tolerances) {
      Job smoothed = planned;
      smoothed.surface->orientation.axis_tolerance_rad = tol * std::numbers::pi / 180.0;
      std::optional<SurfaceSetup> smoothed_setup;
      try {
        smoothed_setup.emplace(SetUpSurface(smoothed));
      } catch (const Error& e) {
        // A pass the axis cannot be smoothed on (a pole, a tolerance too tight): said, not fatal.
        r.notes.push_back(fmt::format("{}: not planned: {}", SmoothedName(tol), e.what()));
        continue;
      }
      std::vector<const PathSource*> passes;
      for (const auto& p : smoothed_setup->passes.passes) passes.push_back(p.get());
      std::vector<PathSamples> samples(passes.size());
      ForEachPass(static_cast<int>(passes.size()), [&](std::size_t k) {
        samples[k] = geometry::SamplePath(*passes[k], spec.sample_step_mm,
                                          fmt::format("{}: pass {}", job.file, k + 1));
      });
      with_each_planner(SmoothedName(tol), [&] {
        smoothed_setup->pass_options.planner = smoothed_setup->link_options.planner =
            setup.pass_options.planner;
        return ExactVariant(c, *smoothed_setup, passes, samples, tol);
      });
    }
  }
  return r;
}

std::string VariantLabel(const VariantResult& variant) {
  return fmt::format("{} ({})", variant.name, interp::PlannerName(variant.planner));
}

const VariantResult& ExactVariantOf(const CompareResult& result, interp::PlannerKind planner,
                                    double axis_tolerance_deg) {
  const VariantResult* found = nullptr;
  for (const auto& v : result.variants) {
    if (v.kind != VariantResult::Kind::kExact) continue;
    if (std::abs(v.axis_tolerance_deg - axis_tolerance_deg) > 1e-9) continue;
    if (found == nullptr || v.planner == planner) found = &v;
    if (v.planner == planner) break;
  }
  if (found == nullptr) throw Error("{}: the comparison has no exact-surface variant", result.job);
  return *found;
}

std::vector<std::string> CompareHeader() {
  return {"variant",           "planner",         "blocks / poles",    "time (s)",
          "passes (s)",        "export dev (um)", "export axis (deg)", "motion dev (um)",
          "motion axis (deg)", "worst ratio",     "limiting axes",     "compute (s)"};
}

std::vector<std::string> CompareCells(const VariantResult& v) {
  const bool exact = v.kind == VariantResult::Kind::kExact;
  return {v.name,
          interp::PlannerName(v.planner),
          exact ? "-" : fmt::format("{}", v.blocks),
          fmt::format("{:.3f}", v.motion_time_s),
          fmt::format("{:.3f}", v.pass_time_s),
          exact ? "-" : fmt::format("{:.4f}", v.export_deviation_mm * 1e3),
          exact ? "-" : fmt::format("{:.4f}", v.export_axis_deviation_deg),
          fmt::format("{:.4f}", v.motion_deviation_mm * 1e3),
          fmt::format("{:.4f}", v.motion_axis_deviation_deg),
          fmt::format("{:.6f}{}", v.verify.worst_ratio, v.verify.Passed() ? "" : " FAIL"),
          v.limiting,
          fmt::format("{:.2f}", v.compute_s)};
}

std::string FormatCompareText(const CompareResult& r) {
  std::vector<std::vector<std::string>> rows{CompareHeader()};
  for (const auto& v : r.variants) rows.push_back(CompareCells(v));
  std::vector<std::size_t> width(rows.front().size(), 0);
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) width[i] = std::max(width[i], row[i].size());
  }
  std::string out = fmt::format("job {} on machine '{}': {} passes, {:.6g} mm\n", r.job, r.machine,
                                r.passes, r.path_length_mm);
  for (const auto& row : rows) {
    for (std::size_t i = 0; i < row.size(); ++i) {
      out += fmt::format("{}{:<{}}", i ? "  " : "", row[i], i + 1 < row.size() ? width[i] : 0);
    }
    out += "\n";
  }
  for (const auto& note : r.notes) out += "note: " + note + "\n";
  return out;
}

std::string FormatCompareCsv(const CompareResult& r) {
  std::string out =
      "variant,planner,tolerance_mm,axis_tolerance_deg,blocks,motion_time_s,pass_time_s,"
      "export_deviation_mm,export_axis_deviation_deg,motion_deviation_mm,"
      "motion_axis_deviation_deg,worst_ratio,verified,limiting,compute_s\n";
  for (const auto& v : r.variants) {
    out += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},\"{}\",{}\n", v.name,
                       interp::PlannerName(v.planner), v.tolerance_mm, v.axis_tolerance_deg,
                       v.blocks, v.motion_time_s, v.pass_time_s, v.export_deviation_mm,
                       v.export_axis_deviation_deg, v.motion_deviation_mm,
                       v.motion_axis_deviation_deg, v.verify.worst_ratio,
                       v.verify.Passed() ? "yes" : "no", v.limiting, v.compute_s);
  }
  return out;
}

std::string FormatCompareMarkdown(const CompareResult& r) {
  const auto line = [](const std::vector<std::string>& cells) {
    std::string out = "|";
    for (const auto& c : cells) out += " " + c + " |";
    return out + "\n";
  };
  std::string out = line(CompareHeader());
  out += "|";
  for (std::size_t i = 0; i < CompareHeader().size(); ++i) out += i == 0 ? "---|" : "---:|";
  out += "\n";
  for (const auto& v : r.variants) out += line(CompareCells(v));
  return out;
}

}  // namespace dtis::io
