// Job and curve files: every malformed input names its file, line and key.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <thread>

#include "dtis/core/error.hpp"
#include "dtis/io/atomic_file.hpp"
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

// The outputs a job does not name are NAME.csv: a name that would place them outside the current
// folder, or leave them nameless (".csv"), is refused as [output] paths are.
TEST(JobFile, ANameKeepsTheOutputsInTheCurrentFolder) {
  for (const std::string name : {"../../escape", "/tmp/escape", "a/../../escape", "", "sub/"}) {
    SCOPED_TRACE(name);
    ExpectError([&] { ParseJob("name = \"" + name + "\"\n" + kJob, "j.toml"); },
                {"j.toml:1: key 'name': expected a name for the outputs (NAME.csv) inside the "
                 "current folder",
                 "got '" + name + "'"});
  }
  EXPECT_EQ(ParseJob("name = \"runs/today\"\n" + kJob, "j.toml").name, "runs/today");
}

std::string FileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A FIFO is written in place, not renamed over: it stays a FIFO and its reader gets the text.
TEST(AtomicFile, WritesAFifoInPlace) {
  const std::string fifo = test::Scratch("atomic.fifo");
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string read;
  std::thread reader([&] { read = FileText(fifo); });
  {
    AtomicFile out(fifo);  // opens when the reader does
    EXPECT_TRUE(out.InPlace());
    out.Write("t,X\n0,1\n");
    out.Commit();
  }
  reader.join();
  EXPECT_EQ(read, "t,X\n0,1\n");
  struct stat st {};
  ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  // Nothing was left beside it.
  for (const auto& e :
       std::filesystem::directory_iterator(std::filesystem::path(fifo).parent_path())) {
    EXPECT_EQ(e.path().filename().string().find(".atomic.fifo.tmp"), std::string::npos);
  }
}

// A device's failed write is an error naming it; /dev/null stays a device. A regular output
// committed together with it is not left behind.
TEST(AtomicFile, ADevicesFailedWriteIsAnErrorAndLeavesNothing) {
  struct stat st {};
  if (::stat("/dev/full", &st) != 0 || !S_ISCHR(st.st_mode) || ::access("/dev/full", W_OK) != 0) {
    GTEST_SKIP() << "no writable /dev/full";
  }
  const std::string regular = test::Scratch("with_full.csv");
  std::filesystem::remove(regular);
  ExpectError(
      [&] {
        AtomicFile a(regular), b("/dev/full");
        a.Write("t,X\n");
        b.Write("t,X\n");
        CommitTogether({&a, &b});
      },
      "/dev/full: write failed (No space left on device)");
  EXPECT_FALSE(std::filesystem::exists(regular));
  {
    AtomicFile out("/dev/null");
    EXPECT_TRUE(out.InPlace());
    out.Write("nothing\n");
    out.Commit();
  }
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  // A regular target is still replaced atomically.
  {
    AtomicFile out(regular);
    EXPECT_FALSE(out.InPlace());
    out.Write("x\n");
    out.Commit();
  }
  EXPECT_EQ(FileText(regular), "x\n");
}

// A G-code job says where the machine is and which work offsets are in force: its [path] from,
// LinuxCNC's parameter file, and [path.work_offsets] over the file's.
TEST(JobFile, GcodeStartAndWorkOffsets) {
  const std::string var = test::Scratch("job_sim.var");
  std::ofstream(var) << "5220\t1.000000\n5221\t10.000000\n5241\t20.000000\n";
  const std::string head = "machine = \"m.toml\"\n[path]\nkind = \"gcode\"\nfile = \"p.ngc\"\n";
  const Job job =
      ParseJob(head + "from = [0, 0, 50]\nparameters = \"" + var +
                   "\"\n[path.work_offsets]\nG55 = [1, 2, 3]\n\"G59.3\" = [4, 5, 6, 7, 8, 9]\n",
               "j.toml");
  EXPECT_EQ(job.path.gcode.from, (std::vector<double>{0, 0, 50}));
  const auto& p = job.path.gcode.parameters;
  EXPECT_EQ(p.at(5221), 10.0);  // the file's G54
  EXPECT_EQ(p.at(5241), 1.0);   // G55 from the job, over the file's 20
  EXPECT_EQ(p.at(5243), 3.0);
  EXPECT_EQ(p.at(5244), 0.0);  // no A given: 0
  EXPECT_EQ(p.at(5381), 4.0);
  EXPECT_EQ(p.at(5386), 9.0);
  ExpectError([&] { ParseJob(head + "[path.work_offsets]\nG60 = [1, 2, 3]\n", "j.toml"); },
              "key 'path.work_offsets.G60': expected a coordinate system, G54 to G59");
  ExpectError([&] { ParseJob(head + "[path.work_offsets]\nG54 = [1, 2]\n", "j.toml"); },
              "key 'path.work_offsets.G54': expected [X, Y, Z] (mm) or [X, Y, Z, A, B, C]");
  ExpectError([&] { ParseJob(head + "from = [1, 2]\n", "j.toml"); },
              "key 'path.from': expected where the machine is");
}

}  // namespace
}  // namespace dtis::io
