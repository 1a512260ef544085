// Streaming to a running machine: what is streamed is what `dtis run` plans with the same
// commit horizon, row for row; an abort, a planner that falls behind and a path that fails mid-way
// all end with the offered stop, at rest and within every limit (checked by the verifier on the
// rows written, and again from the recorded file); the stop law offered by the planner is itself
// a valid continuation wherever it is taken.
#include "dtis/io/stream.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <thread>

#include "dtis/core/error.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/serve_request.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"
#include "fixture_shapes.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

// Keeps every row written, in file units; optionally calls `on_row` after each.
class Capture final : public io::CncOutput {
 public:
  explicit Capture(int axes) : axes_(axes) {}
  void Write(const io::StreamRow& row) override {
    rows.emplace_back(row.q, row.q + axes_);
    index.push_back(row.index);
    if (on_row) on_row(static_cast<long>(rows.size()));
  }
  void Close() override { closed = true; }
  std::vector<std::vector<double>> rows;
  std::vector<long> index;
  std::function<void(long)> on_row;
  bool closed = false;

 private:
  int axes_;
};

io::Job SampleJob(const std::string& name, std::size_t horizon = io::kStreamCommitHorizon) {
  io::Job job = io::LoadJob(test::Source("samples/jobs/" + name + ".toml"));
  job.vpop.commit_horizon = horizon;
  return job;
}

std::vector<std::vector<double>> RowsOf(const interp::SetpointTable& t) {
  std::vector<std::vector<double>> rows(t.Rows());
  for (std::size_t r = 0; r < t.Rows(); ++r) {
    for (const auto& c : t.columns) rows[r].push_back(c[r]);
  }
  return rows;
}

io::StreamResult StreamJob(const io::Job& job, const Machine& machine, Capture* out,
                           io::StreamOptions o = {}, io::Stream** handle = nullptr) {
  o.period_s = job.vpop.period_s;
  o.commit_horizon = job.vpop.commit_horizon;
  io::Stream stream(machine, o);
  if (handle) *handle = &stream;
  const auto segments = io::JobSegments(job, machine);
  return stream.Run(*segments, *out);
}

// Streamed = planned: the 5-axis surface sample, a G-code program (contours, corners, rapids) and
// a NURBS curve give exactly the rows `dtis run` plans with the same horizon, with either planner
// (the look-ahead's grid moves with the planner and is dropped behind the committed steps).
TEST(Stream, EqualsTheRunWithTheSameHorizon) {
  for (const auto planner : {interp::PlannerKind::kVpop, interp::PlannerKind::kLookAhead})
    for (const char* name : {"surface_tilt10_xyzac", "lock", "trident"}) {
      SCOPED_TRACE(fmt::format("{} planned by {}", name, interp::PlannerName(planner)));
      io::Job job = SampleJob(name);
      job.vpop.planner = planner;
      const io::RunResult run = io::RunJob(job);
      Capture out(run.machine->AxisCount());
      const io::StreamResult r = StreamJob(job, *run.machine, &out);
      EXPECT_EQ(r.end, io::StreamEnd::kComplete);
      EXPECT_EQ(r.stop_rows, 0);
      EXPECT_TRUE(out.closed);
      ASSERT_EQ(out.rows.size(), run.table.Rows());
      EXPECT_TRUE(out.rows == RowsOf(run.table));  // bit for bit
      EXPECT_TRUE(r.verify.Passed());
      EXPECT_EQ(r.verify.worst_ratio, run.verify.worst_ratio);
      EXPECT_EQ(r.verify.motion_time_s, run.verify.motion_time_s);
    }
}

// A six-joint arm streams as a mill does: the open pocket on the RX170B (joint positions per
// period) gives the rows the run plans, bit for bit, and an abort half way ends at rest within
// the joints' limits.
TEST(Stream, AnArmStreamsAsTheRunPlansAndStopsAtRest) {
  const io::Job job = SampleJob("open_pocket_rx170b");
  const io::RunResult run = io::RunJob(job);
  ASSERT_EQ(run.machine->AxisCount(), 6);
  Capture out(run.machine->AxisCount());
  const io::StreamResult r = StreamJob(job, *run.machine, &out);
  EXPECT_EQ(r.end, io::StreamEnd::kComplete);
  ASSERT_EQ(out.rows.size(), run.table.Rows());
  EXPECT_TRUE(out.rows == RowsOf(run.table));
  EXPECT_TRUE(r.verify.Passed());
  const long half = static_cast<long>(run.table.Rows() / 2);
  Capture cut(run.machine->AxisCount());
  io::Stream* stream = nullptr;
  cut.on_row = [&](long rows) {
    if (rows == half) stream->Abort();
  };
  const io::StreamResult a = StreamJob(job, *run.machine, &cut, {}, &stream);
  EXPECT_EQ(a.end, io::StreamEnd::kAborted);
  EXPECT_GT(a.stop_rows, 2);
  EXPECT_TRUE(a.verify.Passed()) << interp::FormatReport(a.verify);
  EXPECT_TRUE(a.verify.ends_at_rest);
}

// A flat end riding over the valleys of a wavy face (strategies::SurfacePass::
// RidesOverFromPrevious) streams as the run plans it: the passes are joined by the same straight
// moves, not linked.
TEST(Stream, PassesThatRideOverStreamAsTheRunPlansThem) {
  const std::string step = test::Scratch("wavy_stream.stp");
  test::WriteStep(test::WavyRuledFace(), step);
  io::Job job = test::PlaneClJob(step, "", "kind = \"flat_end\"\nradius_mm = 4",
                                 "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = "
                                 "6\nmax_passes = 3",
                                 test::Scratch("wavy_stream.toml"));
  job.vpop.commit_horizon = io::kStreamCommitHorizon;
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  int rides = 0;
  for (const auto& pass : setup.passes.passes) rides += pass->RidesOverFromPrevious();
  EXPECT_GE(rides, 1);
  const io::RunResult run = io::RunJob(job);
  Capture out(run.machine->AxisCount());
  const io::StreamResult r = StreamJob(job, *run.machine, &out);
  EXPECT_EQ(r.end, io::StreamEnd::kComplete);
  EXPECT_TRUE(out.rows == RowsOf(run.table));  // bit for bit
  EXPECT_TRUE(r.verify.Passed());
}

// A G-code job's feed is its F words; the link from where the machine is to its first block moves
// at the program's rapid feed (here the linear axes' 30 m/min together), never at a placeholder.
TEST(Stream, GcodeLinkMovesAtTheRapidFeed) {
  const io::Job job = SampleJob("lock");
  const auto machine = io::LoadJobMachine(job);
  const io::RunResult run = io::RunJob(job);
  Capture out(machine->AxisCount());
  io::StreamOptions o;
  o.period_s = job.vpop.period_s;
  o.commit_horizon = job.vpop.commit_horizon;
  io::Stream stream(*machine, o);
  AxisVector from(3);
  from << 150.0, 100.0, 50.0;
  const auto segments = io::JobSegments(job, *machine, from);
  const io::StreamResult r = stream.Run(*segments, out);
  ASSERT_EQ(r.end, io::StreamEnd::kComplete);
  EXPECT_TRUE(r.verify.Passed());
  // The link: up, across about 190 mm and down, each at most a few tenths of a second of
  // acceleration at 2.1-3 m/s^2 on top of its length at 500 mm/s.
  const double link_s = static_cast<double>(out.rows.size() - run.table.Rows()) * o.period_s;
  EXPECT_GT(link_s, 0.3);
  EXPECT_LT(link_s, 3.0) << "the link moved at a crawl";
}

// G4 holds the machine at rest for the dwell time, in the run and in the stream alike: the
// program with its dwells plans the rows of the same program with dwells of no time (which still
// stop the machine) plus the dwells' periods (a warm-up before the first cut, a pause at the
// bottom of a plunge, two dwells in a row summed), and the stream sends those very rows.
TEST(Stream, DwellsHoldAtRestInTheRunAndTheStream) {
  const std::string machine = test::Source("samples/machines/mikron_ucp710_xyz.toml");
  const auto job_for = [&](const std::string& name, bool dwells) {
    std::ifstream in(test::Source("tests/data/gcode/dwell.ngc"));
    std::ofstream program(test::Scratch(name + ".ngc"));
    for (std::string line; std::getline(in, line);) {
      program << (dwells || line.rfind("G4", 0) != 0 ? line : "G4 P0") << "\n";
    }
    program.close();
    std::ofstream(test::Scratch(name + ".toml")) << fmt::format(
        "machine = \"{}\"\n[path]\nkind = \"gcode\"\nfile = \"{}.ngc\"\nfrom = [0, 0, 5]\n",
        machine, name);
    io::Job job = io::LoadJob(test::Scratch(name + ".toml"));
    job.vpop.commit_horizon = io::kStreamCommitHorizon;
    return job;
  };
  const io::Job with = job_for("dwell", true), without = job_for("no_dwell", false);
  const io::RunResult run = io::RunJob(with), plain = io::RunJob(without);
  ASSERT_TRUE(run.verify.Passed());
  // 0.4 s before the first cut, 0.25 s at the bottom, 0.1 + 0.15 s at a corner, at 1 ms.
  EXPECT_EQ(run.table.Rows(), plain.table.Rows() + 400 + 250 + 250);
  // The machine starts where the program's G0 goes (its [path] from): the warm-up is before the
  // motion.
  EXPECT_NEAR(run.verify.motion_time_s, plain.verify.motion_time_s + 0.5, 1e-9);
  // The rows are the plain ones with each dwell's rows inserted where it stands.
  const auto rows = RowsOf(run.table), plain_rows = RowsOf(plain.table);
  std::size_t r = 0, held = 0;
  for (const auto& row : plain_rows) {
    while (r < rows.size() && rows[r] != row) {
      EXPECT_EQ(rows[r], rows[r - 1]) << "row " << r << " is neither planned nor held";
      ++r, ++held;
    }
    ASSERT_LT(r, rows.size());
    ++r;
  }
  EXPECT_EQ(held, 900u);
  // Streamed = planned.
  Capture out(run.machine->AxisCount());
  const io::StreamResult streamed = StreamJob(with, *run.machine, &out);
  EXPECT_EQ(streamed.end, io::StreamEnd::kComplete);
  EXPECT_TRUE(out.rows == rows);
  // The summary lists the dwells as held.
  bool listed = false;
  for (const auto& [what, count] : run.gcode_notes) {
    if (what.find("dwell (G4): held at rest") != std::string::npos) listed = count == 4;
  }
  EXPECT_TRUE(listed);
}

// A chain of more than window_blocks blocks is streamed through a window (smoothed as it is
// planned, dropped behind): the rows are still those `dtis run` plans from the whole chain.
TEST(Stream, WindowedChainsStreamAsTheRunPlansThem) {
  for (const auto planner : {interp::PlannerKind::kVpop, interp::PlannerKind::kLookAhead}) {
    SCOPED_TRACE(interp::PlannerName(planner));
    io::Job job = SampleJob("lock");
    job.vpop.planner = planner;
    job.path.gcode.window_blocks = 8;
    const io::RunResult run = io::RunJob(job);  // holds every chain whole
    Capture out(run.machine->AxisCount());
    const io::StreamResult r = StreamJob(job, *run.machine, &out);
    EXPECT_EQ(r.end, io::StreamEnd::kComplete);
    ASSERT_EQ(out.rows.size(), run.table.Rows());
    EXPECT_TRUE(out.rows == RowsOf(run.table));  // bit for bit
  }
}

// An abort at many points of a 5-axis pass: the rows written are the planned ones up to where the
// stop begins, then the stop brings every axis to rest within its limits.
TEST(Stream, AbortAnywhereEndsAtRestWithinTheLimits) {
  const io::Job job = SampleJob("surface_tilt10_xyzac", 64);
  const io::RunResult run = io::RunJob(job);
  const auto planned = RowsOf(run.table);
  const long n = static_cast<long>(planned.size());
  for (const long at : {1L, 5L, 100L, 333L, n / 2, n - 200, n - 3}) {
    SCOPED_TRACE(at);
    Capture out(run.machine->AxisCount());
    io::Stream* stream = nullptr;
    out.on_row = [&](long rows) {
      if (rows == at) stream->Abort();
    };
    const io::StreamResult r = StreamJob(job, *run.machine, &out, {}, &stream);
    ASSERT_GE(r.rows, at);
    const long before_stop = r.rows - r.stop_rows;
    for (long k = 0; k < before_stop; ++k) ASSERT_EQ(out.rows[k], planned[k]) << "row " << k;
    EXPECT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
    EXPECT_TRUE(r.verify.ends_at_rest);
    // The stop starts at the end of the hand-over the abort fell in.
    EXPECT_LE(before_stop - at, r.largest_handover);
    EXPECT_LE(r.largest_handover, 4 * 64);
    // Moving when aborted: a real deceleration, not a hold.
    if (r.end == io::StreamEnd::kAborted && before_stop >= 2 &&
        planned[before_stop - 1] != planned[before_stop - 2]) {
      EXPECT_GT(r.stop_rows, 2);
    }
  }
}

// The stop is offered after every hand-over, so it must be valid wherever it is taken: take each
// offer in turn on the lock contour (a G1 program with corners) and verify the sequence it makes.
class StopProbe final : public interp::SetpointSink {
 public:
  void Accept(const interp::Setpoint& sp) override { rows.push_back(sp); }
  bool WantsStops() const override { return true; }
  void AcceptStop(const std::vector<interp::Setpoint>& stop) override {
    offers.push_back({rows.size(), stop});
  }
  std::vector<interp::Setpoint> rows;
  std::vector<std::pair<std::size_t, std::vector<interp::Setpoint>>> offers;
};

TEST(Stream, EveryOfferedStopIsAValidContinuation) {
  const io::Job job = SampleJob("trident", 32);
  const auto machine = kinematics::LoadMachineFile(job.machine_file);
  const auto path = io::BuildPath(job);
  StopProbe probe;
  interp::PlanVpop(*path, *machine, job.vpop, probe);
  ASSERT_GT(probe.offers.size(), 20u);
  for (const auto& [handed, stop] : probe.offers) {
    SCOPED_TRACE(handed);
    io::TableSink table(*machine, job.vpop.period_s);
    for (std::size_t k = 0; k < handed; ++k) table.Accept(probe.rows[k]);
    for (const auto& sp : stop) {
      ASSERT_EQ(sp.index, static_cast<long>(table.Table().Rows()));  // continues the sequence
      table.Accept(sp);
    }
    const interp::VerifyReport v = interp::Verify(table.Table(), *machine);
    ASSERT_TRUE(v.Passed()) << interp::FormatReport(v);
    // Along the path: never backwards.
    for (std::size_t k = 1; k < stop.size(); ++k) ASSERT_GE(stop[k].s, stop[k - 1].s);
  }
}

// A planner slower than the machine: in real time the buffer drains, and the stream ends with the
// stop before the machine runs dry.
TEST(Stream, AStarvedStreamEndsWithTheStop) {
  const io::Job job = SampleJob("circle", 64);
  const auto machine = kinematics::LoadMachineFile(job.machine_file);
  Capture out(machine->AxisCount());
  io::StreamOptions o;
  o.realtime = true;
  o.buffer_periods = 40;
  o.low_water_periods = 10;
  o.slow_planner_us = 3000;  // three times slower than the 1 ms period
  const io::StreamResult r = StreamJob(job, *machine, &out, o);
  EXPECT_EQ(r.end, io::StreamEnd::kStarved);
  EXPECT_GT(r.stop_rows, 2);
  EXPECT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_LT(r.rows, 3000);  // far from the end of the circle
}

// A path that cannot be followed beyond some arc length: the planner throws, the stream plays the
// stop from the last row handed over and reports the planner's message.
class FailingLine final : public PathSource {
 public:
  FailingLine() : line_({0, 0, 0}, {200, 0, 0}, {0, 0, 1}) {}
  PathState Start() const override { return line_.Start(); }
  std::optional<double> Length() const override { return line_.Length(); }
  PathSample At(const PathState& from, double s) const override {
    PathSample p = line_.At(from, s);
    if (s > 120.0) p.status = PathStatus::kNoConvergence;
    return p;
  }
  std::string Describe(const PathState& state) const override { return line_.Describe(state); }

 private:
  geometry::LinePath line_;
};

class OneSegment final : public io::SegmentSource {
 public:
  explicit OneSegment(io::StreamSegment s) : s_(std::move(s)) {}
  std::optional<io::StreamSegment> Next(const std::optional<AxisVector>&) override {
    if (done_) return std::nullopt;
    done_ = true;
    return s_;
  }

 private:
  io::StreamSegment s_;
  bool done_ = false;
};

TEST(Stream, AFailingPathEndsWithTheStop) {
  const auto machine = test::Cartesian(100.0, 2000.0, 50000.0);
  interp::VpopOptions vo;
  vo.feed_mm_s = 80.0;
  OneSegment segments({std::make_shared<FailingLine>(), vo, "failing line"});
  io::StreamOptions o;
  o.commit_horizon = 64;
  io::Stream stream(*machine, o);
  Capture out(3);
  const io::StreamResult r = stream.Run(segments, out);
  EXPECT_EQ(r.end, io::StreamEnd::kFailed);
  EXPECT_NE(r.error.find("failing line"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("did not converge"), std::string::npos) << r.error;
  EXPECT_GT(r.stop_rows, 2);
  EXPECT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_LE(out.rows.back()[0], 120.0);
}

// The recorded file is what was written, and `dtis verify` reads it to the same report.
TEST(Stream, RecordReadsBackToTheSameReport) {
  const io::Job job = SampleJob("trident", 64);
  const auto machine = kinematics::LoadMachineFile(job.machine_file);
  const std::string file = test::Scratch("stream_record.csv");
  io::StreamResult r;
  {
    io::SetpointWriter record(file, io::AxisNames(*machine));
    io::StreamOptions o;
    o.commit_horizon = 64;
    io::Stream stream(*machine, o);
    Capture out(machine->AxisCount());
    const auto segments = io::JobSegments(job, *machine);
    r = stream.Run(*segments, out, &record);
  }
  const interp::SetpointTable table = io::ReadSetpoints(file);
  std::filesystem::remove(file);
  EXPECT_EQ(static_cast<long>(table.Rows()), r.rows);
  const interp::VerifyReport v = interp::Verify(table, *machine);
  EXPECT_EQ(v.worst_ratio, r.verify.worst_ratio);
  EXPECT_EQ(v.motion_time_s, r.verify.motion_time_s);
}

// The verifier now runs row by row (for streams); check it against the definition written out
// plainly: backward differences over the rows, the first row held before and the last held after.
TEST(Stream, RowByRowVerifierMatchesTheDefinition) {
  const auto machine = test::Cartesian(100.0, 2000.0, 50000.0);
  std::mt19937_64 rng(test::g_seed);
  std::normal_distribution<double> noise(0.0, 1e-4);
  for (int c = 0; c < 50; ++c) {
    const long n = 2 + c * 7;
    std::vector<std::vector<double>> x(3);
    interp::StreamVerifier verifier(*machine, 1e-3);
    for (long k = 0; k < n; ++k) {
      double row[3];
      for (int i = 0; i < 3; ++i) {
        row[i] = (c % 5 == 0 && k == n / 2 ? 1.0 : 0.0) +
                 (c % 3 ? static_cast<double>(k * i) * 1e-3 : 0.0) + noise(rng);
        x[static_cast<std::size_t>(i)].push_back(row[i]);
      }
      verifier.Add(static_cast<double>(k) * 1e-3, row);
    }
    const interp::VerifyReport r = verifier.Report();
    const double dt = 1e-3;
    for (int i = 0; i < 3; ++i) {
      const auto& xi = x[static_cast<std::size_t>(i)];
      const auto at = [&](long k) {
        return xi[static_cast<std::size_t>(std::clamp(k, 0L, n - 1))];
      };
      double v = 0, a = 0, j = 0;
      for (long k = 0; k < n + 2; ++k) {
        v = std::max(v, std::abs(at(k) - at(k - 1)) / dt);
        a = std::max(a, std::abs(at(k) - 2 * at(k - 1) + at(k - 2)) / (dt * dt));
        j = std::max(j,
                     std::abs(at(k) - 3 * at(k - 1) + 3 * at(k - 2) - at(k - 3)) / (dt * dt * dt));
      }
      const auto& axis = r.axes[static_cast<std::size_t>(i)];
      EXPECT_EQ(axis.v, v);
      EXPECT_EQ(axis.a, a);
      EXPECT_EQ(axis.j, j);
      EXPECT_DOUBLE_EQ(axis.j_ratio, j / 50000.0);
    }
    EXPECT_EQ(r.rows, n);
    EXPECT_FALSE(r.ends_at_rest);  // noise on every row
    EXPECT_EQ(r.Passed(), r.worst_ratio <= 1.0 && r.starts_at_rest && r.ends_at_rest);
  }
}

// A job read from a G-code program written for the test (in the scratch folder).
io::Job ProgramJob(const std::string& name, const std::string& program) {
  std::ofstream(test::Scratch(name + ".ngc")) << program;
  std::ofstream(test::Scratch(name + ".toml"))
      << fmt::format("machine = \"{}\"\n[path]\nkind = \"gcode\"\nfile = \"{}.ngc\"\n",
                     test::Source("samples/machines/mikron_ucp710_xyz.toml"), name);
  return io::LoadJob(test::Scratch(name + ".toml"));
}

// A program whose moves take more than the 24 h a job may is refused before anything moves,
// naming the block where its least time (at its F words) passed the bound: moves of 100 mm at
// 1 mm/min take 100 min each, the 15th passes 24 h. 14 of them (23 h 20 min) are accepted.
TEST(Stream, ProgramLongerThanADayIsRefusedAtItsBlock) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto program = [](int moves) {
    std::string text = "G21 G90 G94\nG1 X0 Y0 Z0 F1000\n";
    for (int k = 0; k < moves; ++k) text += fmt::format("G1 X{} F1\n", k % 2 == 0 ? 100 : 0);
    return text + "M2\n";
  };
  test::ExpectError([&] { io::JobSegments(ProgramJob("day_long", program(15)), *machine); },
                    {"day_long.ngc:17:", "more than the 24 h a job may take"});
  EXPECT_NO_THROW(io::JobSegments(ProgramJob("day_short", program(14)), *machine));
}

// A cancelled read throws the reason given, before it reads and while LinuxCNC's interpreter
// runs a program that loops without a move (and so without a record to read): it is stopped.
TEST(Stream, CancelledJobSegmentsThrowTheReason) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  io::Cancel before;
  before.Request("the daemon is shutting down");
  test::ExpectError(
      [&] { io::JobSegments(SampleJob("lock"), *machine, std::nullopt, 5.0, &before); },
      "the daemon is shutting down");
  if (io::DefaultGcodeInterpreter() != io::GcodeInterpreter::kRs274ngc) {
    GTEST_SKIP() << "built without LinuxCNC's interpreter";
  }
  const io::Job idle = ProgramJob(
      "idle_loop", "G21 G90 G94\n#1 = 0\no100 while [1]\n#1 = [#1 + 1]\no100 endwhile\nM2\n");
  io::Cancel during;
  std::string error;
  std::thread read([&] {
    try {
      io::JobSegments(idle, *machine, std::nullopt, 5.0, &during);
    } catch (const Error& e) {
      error = e.what();
    }
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto t0 = std::chrono::steady_clock::now();
  during.Request("cancelled by the test");
  read.join();
  EXPECT_EQ(error, "cancelled by the test");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(2));
}

// An output that fails (its reader died) ends the stream with its error, and the recording holds
// exactly the rows written until then: the start of the whole stream's rows.
TEST(Stream, OutputThatFailsLeavesWhatWasWrittenRecorded) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const io::Job job = SampleJob("circle");
  Capture whole(machine->AxisCount());
  StreamJob(job, *machine, &whole);
  class Failing final : public io::CncOutput {
   public:
    void Write(const io::StreamRow&) override {
      if (++rows_ > 500) throw Error("cannot write the stream: Broken pipe");
    }
    void Close() override {}

   private:
    long rows_ = 0;
  } failing;
  io::StreamOptions o;
  o.period_s = job.vpop.period_s;
  o.commit_horizon = job.vpop.commit_horizon;
  io::Stream stream(*machine, o);
  const std::string file = test::Scratch("failing_output.csv");
  io::SetpointWriter record(file, io::AxisNames(*machine));
  test::ExpectError([&] { stream.Run(*io::JobSegments(job, *machine), failing, &record); },
                    "Broken pipe");
  EXPECT_TRUE(stream.Recorded());
  const interp::SetpointTable recorded = io::ReadSetpoints(file);
  ASSERT_EQ(recorded.Rows(), 500u);
  for (std::size_t r = 0; r < recorded.Rows(); ++r) {
    for (std::size_t i = 0; i < recorded.columns.size(); ++i) {
      ASSERT_EQ(recorded.columns[i][r], whole.rows[r][i]) << "row " << r;
    }
  }
}

// `dtis serve`'s requests: each key once, bounded nesting, a command it knows; every error reply
// one line of valid JSON whatever bytes the request held.
TEST(ServeRequest, RefusesDuplicateKeysDeepNestingAndBytesThatAreNotUtf8) {
  using Command = io::ServeRequest::Command;
  EXPECT_EQ(io::ParseServeRequest(R"({"cmd":"status"})").command, Command::kStatus);
  const io::ServeRequest submit = io::ParseServeRequest(R"({"cmd":"submit","job":"/a b.toml"})");
  EXPECT_EQ(submit.command, Command::kSubmit);
  EXPECT_EQ(submit.job, "/a b.toml");
  test::ExpectError([] { io::ParseServeRequest(R"({"cmd":"status","cmd":"shutdown"})"); },
                    "duplicate key \"cmd\"");
  test::ExpectError([] { io::ParseServeRequest(R"({"cmd":"abort","x":{"y":1,"y":2}})"); },
                    "duplicate key \"y\"");
  EXPECT_EQ(io::ParseServeRequest(R"({"cmd":"pause","x":{"cmd":1},"y":{"cmd":2}})").command,
            Command::kPause);  // the same key in different objects
  test::ExpectError([] { io::ParseServeRequest(R"({"cmd":"status","x":[[[[[[[[[[]]]]]]]]]]})"); },
                    "nested deeper than 8");
  test::ExpectError([] { io::ParseServeRequest(R"({"cmd":"fly"})"); }, "unknown command 'fly'");
  test::ExpectError([] { io::ParseServeRequest(R"({"cmd":"submit","job":"a\u0000b"})"); }, "NUL");
  for (const std::string bad : {"{\"cmd\":\"\xff\"}", "\xc3\x28", "{\"\xed\xa0\x80\":1}"}) {
    try {
      io::ParseServeRequest(bad);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const Error& e) {
      const std::string reply = io::ServeErrorReply(e.what());
      EXPECT_EQ(reply.find('\n'), std::string::npos);
      const auto parsed = nlohmann::json::parse(reply);  // throws on bytes that are not UTF-8
      EXPECT_EQ(parsed["ok"], false);
      EXPECT_NE(parsed["error"].get<std::string>().find("malformed request"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace dtis
