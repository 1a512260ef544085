// Job and curve files: every malformed input names its file, line and key.
#include <gtest/gtest.h>

#include "dtis/core/error.hpp"
#include "dtis/io/curve_file.hpp"
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
