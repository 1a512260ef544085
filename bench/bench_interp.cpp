// Planning speed on the papers' samples, single thread, dt = 1 ms: setpoints per second and the
// real-time factor (motion time / compute time).
//   build/bench/dtis_bench --benchmark_filter=Plan
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <sys/resource.h>
#include <tbb/global_control.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "dtis/interp/program.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/job.hpp"
#include "dtis/kinematics/machines.hpp"
#include "face_with_holes.hpp"

namespace {

struct Count final : dtis::interp::SetpointSink {
  long n = 0;
  void Accept(const dtis::interp::Setpoint&) override { ++n; }
};

using dtis::interp::PlannerKind;

// What the planning benchmarks report: setpoints per second, the real-time factor (seconds of
// motion planned per second of compute), exact pose evaluations per setpoint, and the motion time,
// back-offs and look-ahead repairs of one plan.
void ReportPlanning(benchmark::State& state, long setpoints, double motion,
                    const dtis::interp::VpopSummary& last) {
  state.counters["setpoints_per_s"] =
      benchmark::Counter(static_cast<double>(setpoints), benchmark::Counter::kIsRate);
  state.counters["real_time_factor"] = benchmark::Counter(motion, benchmark::Counter::kIsRate);
  state.counters["evals_per_setpoint"] =
      static_cast<double>(last.evaluations) / static_cast<double>(std::max(last.setpoints, 1L));
  state.counters["motion_s"] = last.motion_time_s;
  state.counters["back_offs"] = static_cast<double>(last.back_offs);
  state.counters["repairs"] = static_cast<double>(last.profile_repairs);
}

// A sample benchmarked with each planner, as FUNC/NAME_lookahead and FUNC/NAME_vpop, FUNC taking
// (state, job file, planner). The paper's planner runs once (it takes seconds on the hard samples);
// with _ONCE the look-ahead too.
#define DTIS_PLANNERS(func, name, file)                                    \
  BENCHMARK_CAPTURE(func, name##_lookahead, file, PlannerKind::kLookAhead) \
      ->Unit(benchmark::kMillisecond);                                     \
  BENCHMARK_CAPTURE(func, name##_vpop, file, PlannerKind::kVpop)           \
      ->Unit(benchmark::kMillisecond)                                      \
      ->Iterations(1)
#define DTIS_PLANNERS_ONCE(func, name, file)                               \
  BENCHMARK_CAPTURE(func, name##_lookahead, file, PlannerKind::kLookAhead) \
      ->Unit(benchmark::kMillisecond)                                      \
      ->Iterations(1);                                                     \
  BENCHMARK_CAPTURE(func, name##_vpop, file, PlannerKind::kVpop)           \
      ->Unit(benchmark::kMillisecond)                                      \
      ->Iterations(1)

// The commit horizon of `dtis stream` (StreamOptions): Streamed/ plans under it, what a stream's
// planner thread does; the others plan whole, as `dtis run` does.
constexpr std::size_t kStreamHorizon = 256;
constexpr std::size_t kWhole = std::numeric_limits<std::size_t>::max();

// A curve or line sample planned alone (the path built once), one thread.
//   build/bench/dtis_bench --benchmark_filter=Plan/
void Plan(benchmark::State& state, const char* job_file, PlannerKind planner,
          std::size_t horizon = kWhole) {
  auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/" + job_file);
  job.vpop.planner = planner;
  job.vpop.commit_horizon = horizon;
  const auto machine = dtis::io::LoadJobMachine(job);
  const auto path = dtis::io::BuildPath(job);
  long setpoints = 0;
  double motion = 0.0;
  dtis::interp::VpopSummary last;
  for (auto _ : state) {
    Count sink;
    last = dtis::interp::PlanVpop(*path, *machine, job.vpop, sink);
    setpoints += sink.n;
    motion += last.motion_time_s;
  }
  ReportPlanning(state, setpoints, motion, last);
}

DTIS_PLANNERS(Plan, line, "samples/jobs/line.toml");
DTIS_PLANNERS(Plan, trident, "samples/jobs/trident.toml");
DTIS_PLANNERS(Plan, circle, "samples/jobs/circle.toml");
DTIS_PLANNERS(Plan, circle_300, "samples/jobs/circle_300.toml");
DTIS_PLANNERS(Plan, open_pocket_bottom, "samples/jobs/open_pocket_bottom.toml");
DTIS_PLANNERS(Plan, open_pocket_xyzac, "samples/jobs/open_pocket_xyzac.toml");

}  // namespace

namespace {

// What the surface benchmarks report: real-time factor, setpoints per second, Newton iterations
// and pose evaluations per setpoint, summed over the timed runs.
struct SurfaceCounts {
  long setpoints = 0, iterations = 0, evaluations = 0;
  double motion = 0.0;
  void Add(const dtis::interp::VpopSummary& total, double motion_time_s) {
    setpoints += total.setpoints;
    iterations += total.path_iterations;
    evaluations += total.evaluations;
    motion += motion_time_s;
  }
  void Report(benchmark::State& state) const {
    state.counters["setpoints_per_s"] =
        benchmark::Counter(static_cast<double>(setpoints), benchmark::Counter::kIsRate);
    state.counters["real_time_factor"] = benchmark::Counter(motion, benchmark::Counter::kIsRate);
    state.counters["newton_per_setpoint"] =
        static_cast<double>(iterations) / static_cast<double>(setpoints);
    state.counters["evals_per_setpoint"] =
        static_cast<double>(evaluations) / static_cast<double>(setpoints);
  }
};

// Times `job` run whole on `threads` threads, with its counts.
void RunSurfaceJob(benchmark::State& state, const dtis::io::Job& job, int threads) {
  dtis::io::RunOptions options;
  options.threads = threads;
  SurfaceCounts counts;
  for (auto _ : state) {
    const auto r = dtis::io::RunJob(job, options);
    counts.Add(r.vpop, r.verify.motion_time_s);
    benchmark::DoNotOptimize(r);
  }
  counts.Report(state);
}

// A whole surface job (STEP read, passes built and traced, passes and links planned), with 1 or 2
// threads.
//   build/bench/dtis_bench --benchmark_filter=Surface/
void Surface(benchmark::State& state, const char* job_file) {
  RunSurfaceJob(state, dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/" + job_file),
                static_cast<int>(state.range(0)));
}

// The same jobs' planning alone, the surface set up once outside the timed loop (STEP read, face
// and passes built), as the curve benchmarks above time the planning of a built path: what an
// open CNC pays per period once the part is loaded.
//   build/bench/dtis_bench --benchmark_filter=SurfacePlan/
void SurfacePlan(benchmark::State& state, const char* job_file) {
  const auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/" + job_file);
  const auto machine = dtis::io::LoadJobMachine(job);
  const auto setup = dtis::io::SetUpSurface(job);
  std::vector<const dtis::PathSource*> passes;
  for (const auto& pass : setup.passes.passes) passes.push_back(pass.get());
  dtis::io::RunOptions options;
  options.threads = static_cast<int>(state.range(0));
  SurfaceCounts counts;
  for (auto _ : state) {
    const auto pp = dtis::io::PlanPasses(passes, setup, *machine, options, job.file);
    counts.Add(pp.program.total, pp.program.total.motion_time_s);
    benchmark::DoNotOptimize(pp);
  }
  counts.Report(state);
}

// A surface job's passes and links planned with either planner, one thread, the part loaded.
//   build/bench/dtis_bench --benchmark_filter=SurfacePlanner/
void SurfacePlanner(benchmark::State& state, const char* job_file, PlannerKind planner,
                    std::size_t horizon = kWhole) {
  auto job = dtis::io::LoadJob(job_file[0] == '/' ? std::string(job_file)
                                                  : std::string(DTIS_SOURCE_DIR) + "/" + job_file);
  job.vpop.planner = planner;
  job.vpop.commit_horizon = horizon;
  const auto machine = dtis::io::LoadJobMachine(job);
  const auto setup = dtis::io::SetUpSurface(job);
  std::vector<const dtis::PathSource*> passes;
  for (const auto& pass : setup.passes.passes) passes.push_back(pass.get());
  dtis::io::RunOptions options;
  options.threads = 1;
  long setpoints = 0;
  double motion = 0.0;
  dtis::interp::VpopSummary last;
  for (auto _ : state) {
    const auto pp = dtis::io::PlanPasses(passes, setup, *machine, options, job.file);
    setpoints += static_cast<long>(pp.program.setpoints.size());
    motion += pp.program.total.motion_time_s;
    last = pp.program.total;
  }
  ReportPlanning(state, setpoints, motion, last);
}
DTIS_PLANNERS_ONCE(SurfacePlanner, tilt10_xyzac, "samples/jobs/surface_tilt10_xyzac.toml");
DTIS_PLANNERS_ONCE(SurfacePlanner, tilt10_singular, "samples/jobs/surface_tilt10_singular.toml");
DTIS_PLANNERS_ONCE(SurfacePlanner, plane_cl_3axis, "samples/jobs/surface_plane_cl_3axis.toml");
// A trimmed rational face of a real part: passes end on its trimming loops.
DTIS_PLANNERS_ONCE(SurfacePlanner, trimmed_face, "bench/jobs/trimmed_face.toml");
// A 5-axis pass over a cubic face, its axis smoothed within 0.09 deg.
DTIS_PLANNERS(SurfacePlanner, cubic_wave_xyzac, "samples/jobs/surface_cubic_wave_xyzac.toml");

// A whole trimmed B-spline face with holes: a wavy ruled face 60 x 60 mm (waves of 3 mm over
// 30 mm) with two round holes of 6 mm radius, made here and written with a plane_cl job (1 mm
// ball, stepover 3 mm, on the XYZ Mikron) into a folder of this run's own.
void SurfacePlannerHoles(benchmark::State& state, PlannerKind planner) {
  static const std::string job = dtis::bench::WriteFaceWithHolesJob();
  SurfacePlanner(state, job.c_str(), planner);
}
BENCHMARK_CAPTURE(SurfacePlannerHoles, holes_lookahead, PlannerKind::kLookAhead)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(SurfacePlannerHoles, holes_vpop, PlannerKind::kVpop)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// The face with holes beside 54 other faces of its part, all checked (the default): pins in the
// holes, walls at its sides, a grid of bosses beyond (bench/face_with_holes.hpp). The whole job,
// one thread: the checks are part of tracing the passes.
//   build/bench/dtis_bench --benchmark_filter='Surface(HolesAmongOthers|/cubic_wave_5axis)'
// checks:0 turns the checks off (`check_faces = "none"`): what they cost.
void SurfaceHolesAmongOthers(benchmark::State& state) {
  static const std::string file = dtis::bench::WriteFaceWithHolesAmongOthersJob();
  auto job = dtis::io::LoadJob(file);
  if (state.range(0) == 0) job.surface->check_faces.emplace();
  RunSurfaceJob(state, job, 1);
}
BENCHMARK(SurfaceHolesAmongOthers)
    ->ArgName("checks")
    ->Arg(1)
    ->Arg(0)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// The whole cubic wave finished 5-axis, its axis smoothed (bench/jobs/cubic_wave_5axis.toml).
BENCHMARK_CAPTURE(Surface, cubic_wave_5axis, "bench/jobs/cubic_wave_5axis.toml")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(Surface, tilt10_xyzac, "samples/jobs/surface_tilt10_xyzac.toml")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(Surface, plane_cl_3axis, "samples/jobs/surface_plane_cl_3axis.toml")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);
// A 5-axis pass over a cubic face, its axis smoothed within 0.09 deg: the law's fit is part of
// building the passes.
BENCHMARK_CAPTURE(Surface, cubic_wave_xyzac, "samples/jobs/surface_cubic_wave_xyzac.toml")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(SurfacePlan, cubic_wave_xyzac, "samples/jobs/surface_cubic_wave_xyzac.toml")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(SurfacePlan, tilt10_xyzac, "samples/jobs/surface_tilt10_xyzac.toml")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(SurfacePlan, plane_cl_3axis, "samples/jobs/surface_plane_cl_3axis.toml")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);
// A trimmed face of a real part (bench/jobs/trimmed_face.toml): the trim classification's cost.
BENCHMARK_CAPTURE(SurfacePlan, trimmed_face, "bench/jobs/trimmed_face.toml")
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(1);

}  // namespace

namespace {

// Reading G-code: a generated 100 000-block program (a zigzag of G1 blocks with a few arcs).
//   build/bench/dtis_bench --benchmark_filter=Gcode
void GcodeRead(benchmark::State& state) {
  std::string text = "G21 G90 G17\nG0 X0 Y0 Z1\nG1 Z0 F3000\n";
  for (int k = 0; k < 100000; ++k) {
    if (k % 50 == 49) {
      text += "G3 X" + std::to_string(k * 0.1) + " Y0 R0.05\n";
    } else {
      text += "G1 X" + std::to_string(k * 0.1 + 0.05) + " Y" + std::to_string((k % 7) * 0.013) +
              " Z-0.0" + std::to_string(k % 10) + "\n";
    }
  }
  long blocks = 0;
  for (auto _ : state) {
    const auto p = dtis::io::ParseGcode(text, "bench.ngc");
    blocks += static_cast<long>(p.moves.size());
    benchmark::DoNotOptimize(p);
  }
  state.counters["blocks_per_s"] =
      benchmark::Counter(static_cast<double>(blocks), benchmark::Counter::kIsRate);
}
BENCHMARK(GcodeRead)->Unit(benchmark::kMillisecond);

// Planning G-code, single thread: corner smoothing and VPOp on the lock sample, and on a
// 98 300-block program (a raster of 100 rows of 100 mm, each cut into 0.1 mm G1 blocks with 1 mm
// blocks at both ends, as CAM exports a planar face; 1 mm steps and 90 degree corners between
// rows). Setpoints per second
// and the real-time factor.
//   build/bench/dtis_bench --benchmark_filter=GcodePlan
void GcodePlanOn(benchmark::State& state, const dtis::io::GcodeProgram& program,
                 const dtis::io::Job& job) {
  const auto machine = dtis::io::LoadJobMachine(job);
  long setpoints = 0;
  double motion = 0.0;
  dtis::interp::VpopSummary last;
  dtis::interp::ProgramOptions po;
  po.threads = 1;
  // One thread for the corners too (BuildGcodePlan builds them on all cores otherwise).
  const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  for (auto _ : state) {
    const auto plan = dtis::io::BuildGcodePlan(program, *machine, job.vpop, job.path.gcode);
    const auto result = dtis::interp::PlanProgram(plan.segments, *machine, po);
    setpoints += static_cast<long>(result.setpoints.size());
    motion += result.total.motion_time_s;
    last = result.total;
  }
  state.counters["blocks"] = static_cast<double>(program.moves.size());
  ReportPlanning(state, setpoints, motion, last);
}

// A G-code sample with either planner (its program read once).
void GcodePlanSample(benchmark::State& state, const char* job_file, PlannerKind planner,
                     std::size_t horizon = kWhole) {
  auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/" + job_file);
  job.vpop.planner = planner;
  job.vpop.commit_horizon = horizon;
  GcodePlanOn(state, dtis::io::ReadGcode(job.path.gcode_file), job);
}
DTIS_PLANNERS(GcodePlanSample, lock, "samples/jobs/lock.toml");
DTIS_PLANNERS_ONCE(GcodePlanSample, fine_wave, "samples/jobs/fine_wave.toml");
DTIS_PLANNERS_ONCE(GcodePlanSample, five_axis_g1, "samples/jobs/five_axis_g1.toml");

// A sample planned as `dtis stream` plans it, under its commit horizon (each hand-over waits for a
// proven stop to rest), one thread: the real-time factor a stream of it has.
//   build/bench/dtis_bench --benchmark_filter=Streamed/
void Streamed(benchmark::State& state, const char* job_file, PlannerKind planner) {
  const auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/" + job_file);
  if (job.surface) {
    SurfacePlanner(state, job_file, planner, kStreamHorizon);
  } else if (job.path.kind == dtis::io::PathSpec::Kind::kGcode) {
    GcodePlanSample(state, job_file, planner, kStreamHorizon);
  } else {
    Plan(state, job_file, planner, kStreamHorizon);
  }
}
DTIS_PLANNERS_ONCE(Streamed, trident, "samples/jobs/trident.toml");
DTIS_PLANNERS_ONCE(Streamed, circle_300, "samples/jobs/circle_300.toml");
DTIS_PLANNERS_ONCE(Streamed, open_pocket_xyzac, "samples/jobs/open_pocket_xyzac.toml");
DTIS_PLANNERS_ONCE(Streamed, lock, "samples/jobs/lock.toml");
DTIS_PLANNERS_ONCE(Streamed, fine_wave, "samples/jobs/fine_wave.toml");
DTIS_PLANNERS_ONCE(Streamed, five_axis_g1, "samples/jobs/five_axis_g1.toml");
DTIS_PLANNERS_ONCE(Streamed, tilt10_head_table, "samples/jobs/surface_tilt10_head_table.toml");
DTIS_PLANNERS_ONCE(Streamed, plane_cl_3axis, "samples/jobs/surface_plane_cl_3axis.toml");
DTIS_PLANNERS_ONCE(Streamed, leading_line_3axis, "samples/jobs/surface_leading_line_3axis.toml");
// The paper's planner streams the singular pass at 0.02x (three minutes): not benchmarked.
BENCHMARK_CAPTURE(Streamed, tilt10_singular_lookahead, "samples/jobs/surface_tilt10_singular.toml",
                  PlannerKind::kLookAhead)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

void GcodePlan100k(benchmark::State& state) {
  const auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/samples/jobs/lock.toml");
  std::string text = "G21 G90 G17\nG0 X-50 Y-50 Z0\nG1 F3000\n";
  for (int row = 0; row < 100; ++row) {
    const double y = -50.0 + row;
    if (row > 0) text += "Y" + std::to_string(y) + "\n";
    // 1 mm blocks at both ends of a row, 0.1 mm between.
    for (int k = 10; k <= 1000; k = k < 990 ? k + 1 : k + 10) {
      const double x = row % 2 == 0 ? -50.0 + 0.1 * k : 50.0 - 0.1 * k;
      text += "X" + std::to_string(x) + "\n";
    }
  }
  GcodePlanOn(state, dtis::io::ParseGcode(text, "raster.ngc"), job);
}
BENCHMARK(GcodePlan100k)->Unit(benchmark::kMillisecond)->Iterations(1);

// A program whose every vertex is a corner, as CAM exports a curved contour: 2 000 blocks of 1 mm,
// each turning 1 degree (a polygon of a 57 mm circle, 5.6 turns), F 3 m/min, lock.toml's machine.
// Each corner turns within 0.25 mm, so the axis jerk limits the feed at nearly every period (the
// circle itself would allow F): the planner backs off ~15 times per block.
void GcodePlanPolygon(benchmark::State& state) {
  const auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/samples/jobs/lock.toml");
  std::string text = "G21 G90 G17\nG0 X0 Y0 Z0\nG1 F3000\n";
  double x = 0.0, y = 0.0;
  for (int k = 1; k <= 2000; ++k) {
    const double heading = k * std::numbers::pi / 180.0;
    x += std::cos(heading);
    y += std::sin(heading);
    text += fmt::format("X{:.4f} Y{:.4f}\n", x, y);
  }
  GcodePlanOn(state, dtis::io::ParseGcode(text, "polygon.ngc"), job);
}
BENCHMARK(GcodePlanPolygon)->Unit(benchmark::kMillisecond)->Iterations(1);

// Loading a million-block program: reading it and smoothing its corners (what happens before the
// first setpoint): rows of 1 000 blocks of 0.1 mm along a gentle wave in Z, 1 mm apart (Z written
// to 0.1 um, so some neighbours come out collinear): 456 460 corners. Corners are built on all
// cores.
//   build/bench/dtis_bench --benchmark_filter=GcodeLoad1M
void GcodeLoad1M(benchmark::State& state) {
  const auto job = dtis::io::LoadJob(std::string(DTIS_SOURCE_DIR) + "/samples/jobs/lock.toml");
  const auto machine = dtis::io::LoadJobMachine(job);
  std::string text = "G21 G90 G17\nG0 X0 Y0 Z1\nG1 Z0 F3000\n";
  for (int row = 0, n = 0; n < 1000000; ++row) {
    for (int i = 0; i < 1000; ++i, ++n) {
      const int k = row % 2 == 0 ? i : 999 - i;
      text += fmt::format("G1 X{:.3f} Y{:.3f} Z{:.4f}\n", 0.1 * k, 1.0 * row,
                          0.05 * std::sin(0.01 * k + row));
    }
  }
  long blocks = 0, corners = 0;
  for (auto _ : state) {
    const auto program = dtis::io::ParseGcode(text, "wave.ngc");
    const auto plan = dtis::io::BuildGcodePlan(program, *machine, job.vpop, job.path.gcode);
    blocks += static_cast<long>(program.moves.size());
    corners += plan.corners;
  }
  state.counters["blocks_per_s"] =
      benchmark::Counter(static_cast<double>(blocks), benchmark::Counter::kIsRate);
  state.counters["corners"] =
      static_cast<double>(corners) / static_cast<double>(state.iterations());
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  state.counters["peak_rss_mb"] = static_cast<double>(usage.ru_maxrss) / 1024.0;
}
BENCHMARK(GcodeLoad1M)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace

#undef DTIS_PLANNERS
#undef DTIS_PLANNERS_ONCE
