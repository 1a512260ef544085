// Job and curve files: every malformed input names its file, line and key.
#include <gtest/gtest.h>

#include "dtis/core/error.hpp"
#include "dtis/io/curve_file.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "test_support.hpp"

namespace dtis::io {
namespace {

using test::ExpectError;

const std::string kJob = R"(machine = "m.toml"
feed_mm_min = 5000
[path]
kind = "line"
from = [0, 0, 0]
to = [100, 0, 0]
)";

TEST(JobFile, ReadsAndConverts) {
  const Job job = ParseJob(kJob + "[tangential]\njerk_mm_s3 = 7000\n", "/jobs/a.toml");
  EXPECT_EQ(job.machine_file, "/jobs/m.toml");
  EXPECT_DOUBLE_EQ(job.vpop.feed_mm_s, 5000.0 / 60.0);
  EXPECT_DOUBLE_EQ(job.vpop.period_s, 1e-3);
  EXPECT_DOUBLE_EQ(job.vpop.tangential_jerk_mm_s3, 7000.0);
  EXPECT_EQ(job.name, "a");
}

TEST(JobFile, BadInputNamesFileLineAndKey) {
  ExpectError([] { ParseJob(kJob + "feedrate = 3\n", "j.toml"); },
              "j.toml:7: unknown key 'path.feedrate'");
  ExpectError([] { ParseJob("period_ms = 0\n" + kJob, "j.toml"); },
              "j.toml:1: key 'period_ms': expected a number > 0, got 0");
  ExpectError([] { ParseJob("period_ms = -1\n" + kJob, "j.toml"); }, "key 'period_ms'");
  ExpectError([] { ParseJob("machine = \"m.toml\"\nfeed_mm_min = nan\n", "j.toml"); },
              "key 'feed_mm_min': expected a finite number");
  ExpectError([] { ParseJob("feed_mm_min = 100\n", "j.toml"); }, "missing key 'machine'");
  ExpectError([] { ParseJob(kJob + "[interpolator]\nprofile = \"bell\"\n", "j.toml"); },
              "key 'interpolator.profile': only used by");
  ExpectError([] { ParseJob(kJob + "[path2]\n", "j.toml"); }, "unknown key 'path2'");
  ExpectError([] { LoadJob("/nonexistent/job.toml"); }, "/nonexistent/job.toml: cannot open");
}

TEST(JobFile, GcodePathOptions) {
  const std::string gcode = "machine = \"m.toml\"\n[path]\nkind = \"gcode\"\nfile = \"p.ngc\"\n";
  EXPECT_TRUE(ParseJob(gcode, "j.toml").path.gcode.blend_rapids);
  EXPECT_FALSE(ParseJob(gcode + "blend_rapids = false\n", "j.toml").path.gcode.blend_rapids);
  ExpectError([&] { ParseJob(gcode + "blend_rapids = 1\n", "j.toml"); },
              "j.toml:5: key 'path.blend_rapids'");
  EXPECT_EQ(ParseJob(gcode, "j.toml").path.gcode.window_blocks, 4096u);
  EXPECT_EQ(ParseJob(gcode + "window_blocks = 0\n", "j.toml").path.gcode.window_blocks, 0u);
  ExpectError([&] { ParseJob(gcode + "window_blocks = -1\n", "j.toml"); },
              "j.toml:5: key 'path.window_blocks': expected 0 or more blocks, got -1");
}

TEST(CurveFile, BadInputNamesFileLineAndItem) {
  const std::string head = "degree = 2\n";
  const std::string poles = "poles = [[0, 0], [1, 1], [2, 0]]\n";
  EXPECT_NO_THROW(ParseCurveFile(head + "knots = [0, 0, 0, 1, 1, 1]\n" + poles, "c.toml"));
  ExpectError([&] { ParseCurveFile(head + "knots = [0, 0, 1, 0.5, 1, 1]\n" + poles, "c.toml"); },
              "c.toml:2: curve: knots must not decrease, but knot 3");
  ExpectError([&] { ParseCurveFile(head + "knots = [0, 0, 0, 1, 1]\n" + poles, "c.toml"); },
              "c.toml:2: curve: 5 knots for 3 poles");
  ExpectError(
      [&] {
        ParseCurveFile(head + "knots = [0, 0, 0, 1, 1, 1]\n" + poles + "weights = [1, 0, 1]\n",
                       "c.toml");
      },
      "c.toml:4: curve: weight 1 is 0");
  ExpectError(
      [&] { ParseCurveFile(head + "knots = [0, 0, 0, 1, 1, 1]\npoles = [[0]]\n", "c.toml"); },
      "c.toml:3: key 'poles': point 0 is not [x, y] or [x, y, z]");
}

// A curve that stays on one point is refused as a zero-length line is.
TEST(CurveFile, CoincidentPolesAreRefused) {
  ExpectError(
      [] {
        ParseCurveFile("degree = 2\nknots = [0, 0, 0, 1, 1, 1]\npoles = [[1, 2], [1, 2], [1, 2]]\n",
                       "c.toml");
      },
      "c.toml:3: key 'poles': all 3 poles coincide at (1, 2, 0): the curve has zero length");
}

// Keys that would make a run do nothing or never end are refused where they are read.
TEST(JobFile, NonsenseIsRefusedNamingTheKey) {
  ExpectError([] { ParseJob(kJob + "[interpolator]\nend_tolerance_mm = 1e6\n", "j.toml"); },
              "j.toml:8: key 'interpolator.end_tolerance_mm': expected a distance up to 0.01 mm");
  EXPECT_DOUBLE_EQ(
      ParseJob(kJob + "[interpolator]\nend_tolerance_mm = 0.01\n", "j.toml").vpop.end_tolerance_mm,
      0.01);
  ExpectError([] { ParseJob(kJob + "[interpolator]\ncommit_horizon = 1099511627776\n", "j.toml"); },
              "j.toml:8: key 'interpolator.commit_horizon': expected 8 to 1073741824 periods");
  EXPECT_EQ(ParseJob(kJob + "[interpolator]\ncommit_horizon = 1073741824\n", "j.toml")
                .vpop.commit_horizon,
            std::size_t{1} << 30);
  ExpectError([] { ParseJob("name = \"\"\n" + kJob, "j.toml"); },
              "j.toml:1: key 'name': expected a name");
  const std::string gcode = "machine = \"m.toml\"\n[path]\nkind = \"gcode\"\nfile = \"p.ngc\"\n";
  EXPECT_EQ(ParseJob(gcode, "j.toml").path.gcode.max_blocks, GcodeOptions::kDefaultMaxBlocks);
  EXPECT_EQ(ParseJob(gcode + "max_blocks = 0\n", "j.toml").path.gcode.max_blocks, 0);
  ExpectError([&] { ParseJob(gcode + "max_blocks = -1\n", "j.toml"); },
              "j.toml:5: key 'path.max_blocks': expected 0 (no limit) or more blocks, got -1");
}

// The least time of a motion bounds it before planning: a day for every run, and for `dtis run`,
// which holds its setpoints, kMaxRunSetpoints at the period; each error names the key.
TEST(JobFile, RunsAreBoundedBeforePlanning) {
  const Job line = ParseJob(kJob, "j.toml");  // 100 mm at 5000 mm/min
  EXPECT_NO_THROW(CheckRunBound(line, 100.0));
  Job slow = ParseJob(kJob + "[tangential]\nacceleration_mm_s2 = 1e-6\n", "j.toml");
  EXPECT_NO_THROW(CheckMotionBound(slow, 100.0));  // 5.56 h: a stream may take it
  ExpectError([&] { CheckRunBound(slow, 100.0); },
              "j.toml: the path (100 mm) takes at least 5.56 h with [tangential] "
              "acceleration_mm_s2 = 1e-06: 2e+07 setpoints at 1 ms, more than the 10 million "
              "`dtis run` holds in memory");
  Job taylor =
      ParseJob(kJob + "[interpolator]\nkind = \"taylor2\"\naccel_time_s = 1e9\n", "j.toml");
  ExpectError([&] { CheckMotionBound(taylor, 100.0); },
              "with [interpolator] accel_time_s = 1e+09, more than the 24 h a job may take");
  const Job gcode =
      ParseJob("machine = \"m.toml\"\n[path]\nkind = \"gcode\"\nfile = \"p.ngc\"\n", "j.toml");
  EXPECT_NO_THROW(CheckRunBound(gcode, 100.0, 3600.0));
  ExpectError([&] { CheckRunBound(gcode, 100.0, 3.0 * 3600.0); },
              "with the program's F words, rapids and dwells: 1.08e+07 setpoints");
}

// Periods too short for the machine and limits too small for the period name the key to change,
// with the shortest period the machine allows.
TEST(JobFile, PeriodsTheMachineCannotTakeNameTheKey) {
  const std::string machine = test::Source("samples/machines/mikron_ucp710_xyz.toml");
  const std::string job = "machine = \"" + machine + "\"\n" + kJob.substr(kJob.find('\n') + 1);
  EXPECT_NO_THROW(LoadJobMachine(ParseJob(job, "j.toml")));
  EXPECT_NO_THROW(LoadJobMachine(ParseJob("period_ms = 0.2\n" + job, "j.toml")));
  ExpectError([&] { LoadJobMachine(ParseJob("period_ms = 0.01\n" + job, "j.toml")); },
              {"j.toml: period_ms = 0.01 is shorter than machine 'Mikron UCP 710 XYZ",
               "its jerk limit (5000 mm/s^3)", "expected period_ms of at least 0.166"});
  ExpectError(
      [&] {
        LoadJobMachine(ParseJob(job + "[interpolator]\nlimit_fraction = 1e-300\n", "j.toml"));
      },
      {"j.toml: [interpolator] limit_fraction = 1e-300: at period_ms = 1 rounding the written "
       "positions of axis X",
       "expected a limit_fraction of at least"});
  // The least limit_fraction it names plans.
  const std::string fraction = job + "[interpolator]\nlimit_fraction = 1e-9\n";
  try {
    LoadJobMachine(ParseJob(fraction, "j.toml"));
    FAIL() << "a limit_fraction of 1e-9 planned";
  } catch (const Error& e) {
    const std::string what = e.what();
    const double least = std::stod(what.substr(what.rfind(' ') + 1));
    EXPECT_NO_THROW(LoadJobMachine(ParseJob(
        job + fmt::format("[interpolator]\nlimit_fraction = {:.17g}\n", least * 1.01), "j.toml")));
  }
}

TEST(SetpointFile, RoundTripsExactly) {
  interp::SetpointTable t;
  t.axes = {"X", "Y", "Z", "A", "C"};
  t.columns.resize(5);
  for (int k = 0; k < 100; ++k) {
    t.t.push_back(k * 1e-3);
    for (int i = 0; i < 5; ++i)
      t.columns[static_cast<std::size_t>(i)].push_back(std::sin(k * 0.1 + i) * 123.456789);
  }
  const std::string path = test::Scratch("roundtrip.csv");
  WriteSetpoints(path, t);
  const auto back = ReadSetpoints(path);
  EXPECT_EQ(back.axes, t.axes);
  EXPECT_EQ(back.t, t.t);
  EXPECT_EQ(back.columns, t.columns);
  ExpectError([] { ParseSetpoints("t,X\n0,1\n0.001,x\n", "s.csv"); },
              "s.csv:3: column 2 ('X') is not a finite number");
}

}  // namespace
}  // namespace dtis::io
