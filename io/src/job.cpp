#include "dtis/io/job.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include "dtis/core/error.hpp"
#include "dtis/core/toml_reader.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/curve_file.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::io {
namespace {

Job ReadJob(TomlTable& root) {
  Job job;
  job.file = root.File();
  job.name = root.OptionalString("name").value_or(std::filesystem::path(job.file).stem().string());
  job.machine_file = ResolveRelative(job.file, root.String("machine"));
  const double period_ms = root.OptionalPositiveNumber("period_ms").value_or(1.0);
  job.vpop.period_s = period_ms * 1e-3;
  job.vpop.feed_mm_s = root.PositiveNumber("feed_mm_min") / 60.0;

  TomlTable path = root.Table("path");
  const std::string kind = path.Choice("kind", {"line", "curve"});
  if (kind == "line") {
    job.path.kind = PathSpec::Kind::kLine;
    job.path.from = path.Point("from");
    job.path.to = path.Point("to");
    if ((job.path.to - job.path.from).norm() == 0.0) path.Fail("to", "the line has zero length");
  } else {
    job.path.kind = PathSpec::Kind::kCurve;
    job.path.curve_file = ResolveRelative(job.file, path.String("file"));
  }
  if (const auto axis = path.OptionalPoint("tool_axis")) {
    if (!(axis->norm() > 0.0)) path.Fail("tool_axis", "expected a non-zero vector");
    job.path.tool_axis = axis->normalized();
  }
  path.RejectUnknown();

  if (auto t = root.OptionalTable("tangential")) {
    if (auto a = t->OptionalPositiveNumber("acceleration_mm_s2")) {
      job.vpop.tangential_acceleration_mm_s2 = *a;
    }
    if (auto j = t->OptionalPositiveNumber("jerk_mm_s3")) job.vpop.tangential_jerk_mm_s3 = *j;
    t->RejectUnknown();
  }

  if (auto in = root.OptionalTable("interpolator")) {
    const auto k = in->OptionalChoice("kind", {"vpop", "taylor1", "taylor2"}).value_or("vpop");
    job.interpolator = k == "vpop"      ? InterpolatorKind::kVpop
                       : k == "taylor1" ? InterpolatorKind::kTaylor1
                                        : InterpolatorKind::kTaylor2;
    if (auto f = in->OptionalPositiveNumber("limit_fraction")) {
      if (*f > 1.0)
        in->Fail("limit_fraction", fmt::format("expected a number in (0, 1], got {}", *f));
      job.vpop.limit_fraction = *f;
    }
    if (auto e = in->OptionalPositiveNumber("end_tolerance_mm")) job.vpop.end_tolerance_mm = *e;
    if (auto h = in->OptionalInteger("commit_horizon")) {
      if (*h < 8)
        in->Fail("commit_horizon", fmt::format("expected at least 8 periods, got {}", *h));
      job.vpop.commit_horizon = static_cast<std::size_t>(*h);
    }
    if (auto a = in->OptionalPositiveNumber("arc_length_tolerance_mm")) {
      job.arc_length.tolerance_mm = *a;
    }
    const bool taylor = job.interpolator != InterpolatorKind::kVpop;
    for (const char* key : {"profile", "accel_time_s"}) {
      if (!taylor && in->Has(key)) in->Fail(key, "only used by kind = \"taylor1\" or \"taylor2\"");
    }
    job.taylor.order = job.interpolator == InterpolatorKind::kTaylor1 ? 1 : 2;
    if (auto p = in->OptionalChoice("profile", {"trapezoid", "exponential", "bell"})) {
      job.taylor.profile = interp::ParseFeedProfile(*p);
    }
    if (auto ta = in->OptionalPositiveNumber("accel_time_s")) job.taylor.accel_time_s = *ta;
    in->RejectUnknown();
  }
  job.taylor.period_s = job.vpop.period_s;
  job.taylor.feed_mm_s = job.vpop.feed_mm_s;

  if (auto out = root.OptionalTable("output")) {
    job.setpoints_out = out->OptionalString("setpoints").value_or("");
    job.limiters_out = out->OptionalString("limiters").value_or("");
    out->RejectUnknown();
  }
  root.RejectUnknown();
  std::string why;
  if (!job.vpop.IsValid(&why)) throw Error("{}: {}", job.file, why);
  return job;
}

}  // namespace

Job ParseJob(std::string_view text, const std::string& source_name) {
  TomlTable root = TomlTable::ParseString(text, source_name);
  return ReadJob(root);
}

Job LoadJob(const std::string& path) {
  TomlTable root = TomlTable::ParseFile(path);
  return ReadJob(root);
}

std::unique_ptr<PathSource> BuildPath(const Job& job) {
  if (job.path.kind == PathSpec::Kind::kLine) {
    return std::make_unique<geometry::LinePath>(job.path.from, job.path.to, job.path.tool_axis);
  }
  CurveFile curve = LoadCurveFile(job.path.curve_file);
  try {
    if (curve.top) {
      return std::make_unique<geometry::CurvePath>(std::move(curve.bottom), std::move(*curve.top),
                                                   job.arc_length);
    }
    return std::make_unique<geometry::CurvePath>(std::move(curve.bottom), job.path.tool_axis,
                                                 job.arc_length);
  } catch (const Error& e) {
    throw Error("{}: {}", job.path.curve_file, e.what());
  }
}

RunResult RunJob(const Job& job) {
  RunResult r;
  r.machine = kinematics::LoadMachineFile(job.machine_file);
  const auto path = BuildPath(job);
  r.path_length_mm = path->Length().value_or(0.0);
  TableSink sink(*r.machine, job.vpop.period_s);
  const auto start = std::chrono::steady_clock::now();
  if (job.interpolator == InterpolatorKind::kVpop) {
    try {
      r.vpop = interp::PlanVpop(*path, *r.machine, job.vpop, sink);
    } catch (const Error& e) {
      throw Error("{}: {}", job.file, e.what());
    }
  } else {
    const auto* curve = dynamic_cast<const geometry::CurvePath*>(path.get());
    if (!curve || curve->Top()) {
      throw Error(
          "{}: the Taylor interpolators run on 3-axis curves (path kind = \"curve\" "
          "without a [top] curve)",
          job.file);
    }
    const auto& c = curve->Bottom();
    r.taylor = interp::PlanTaylor(
        [&c](double u, int order, Eigen::Vector3d* d) { c.Derivatives(u, order, d); },
        c.FirstParameter(), c.LastParameter(), curve->Map().Length(), job.taylor);
    AxisVector q, previous;
    for (std::size_t k = 0; k < r.taylor.points.size(); ++k) {
      const InverseResult ir =
          r.machine->Inverse({r.taylor.points[k], job.path.tool_axis}, k ? &previous : nullptr, &q);
      if (ir.status != InverseStatus::kOk) {
        throw Error("{}: {}", job.file, DescribeInverseFailure(*r.machine, ir));
      }
      interp::Setpoint sp;
      sp.index = static_cast<long>(k);
      sp.q = q;
      sink.Accept(sp);
      previous = q;
    }
  }
  r.compute_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.table = sink.Table();
  r.arc_length = sink.ArcLength();
  r.limiters = sink.Limiters();
  r.verify = interp::Verify(r.table, *r.machine);
  return r;
}

std::string FormatRunSummary(const Job& job, const RunResult& r) {
  std::string out = fmt::format("job {}: {} on machine '{}', path {:.6g} mm\n", job.name,
                                job.interpolator == InterpolatorKind::kVpop      ? "VPOp"
                                : job.interpolator == InterpolatorKind::kTaylor1 ? "Taylor order 1"
                                                                                 : "Taylor order 2",
                                r.machine->Name(), r.path_length_mm);
  out += fmt::format("motion time      {:.6f} s\n", r.verify.motion_time_s);
  out += fmt::format("setpoints        {} at {:.6g} ms\n", r.verify.rows, job.vpop.period_s * 1e3);
  out += fmt::format("worst ratio      {:.6f} ({}){}\n", r.verify.worst_ratio, r.verify.worst,
                     r.verify.Passed() ? "" : "  ** the verifier FAILS this sequence **");
  const double rt = r.compute_s > 0 ? r.verify.motion_time_s / r.compute_s : 0.0;
  out += fmt::format("compute time     {:.6f} s ({:.0f}x real time)\n", r.compute_s, rt);
  if (job.interpolator == InterpolatorKind::kVpop) {
    out += fmt::format("back-offs        {} ({} brake tests), {} evaluations\n", r.vpop.back_offs,
                       r.vpop.brake_tests, r.vpop.evaluations);
    out += "limited by      ";
    for (int k = 0; k < static_cast<int>(interp::Limiter::kCount); ++k) {
      const long n = r.vpop.limited_by[static_cast<std::size_t>(k)];
      if (n == 0) continue;
      out += fmt::format(" {} {:.1f}%", interp::LimiterName(static_cast<interp::Limiter>(k)),
                         100.0 * static_cast<double>(n) / static_cast<double>(r.vpop.setpoints));
    }
    out += "\n";
  } else {
    out += fmt::format("feed fluctuation max {:.3e}, rms {:.3e} (of F; profile {})\n",
                       r.taylor.max_fluctuation, r.taylor.rms_fluctuation,
                       interp::FeedProfileName(job.taylor.profile));
    out += fmt::format("end error        {:.3e} mm\n", r.taylor.end_error_mm);
  }
  return out;
}

void WriteRunOutputs(const Job& job, const RunResult& r, const std::string& setpoints_path,
                     const std::string& limiters_path) {
  if (!limiters_path.empty()) {
    AtomicFile out(limiters_path);
    fmt::memory_buffer buf;
    fmt::format_to(std::back_inserter(buf), "t,s,feed,limiter,axis\n");
    const double dt = job.vpop.period_s;
    for (std::size_t k = 0; k < r.limiters.size(); ++k) {
      const double feed = k ? (r.arc_length[k] - r.arc_length[k - 1]) / dt : 0.0;
      const auto& l = r.limiters[k];
      const std::string axis =
          l.axis >= 0 ? r.table.axes[static_cast<std::size_t>(l.axis)] : std::string();
      fmt::format_to(std::back_inserter(buf), "{},{},{},{},{}\n", r.table.t[k], r.arc_length[k],
                     feed, interp::LimiterName(l.kind), axis);
    }
    out.Write({buf.data(), buf.size()});
    // Both files land together or not at all: commit the setpoints first, they matter most.
    WriteSetpoints(setpoints_path, r.table);
    out.Commit();
    return;
  }
  WriteSetpoints(setpoints_path, r.table);
}

}  // namespace dtis::io
