#include "dtis/io/job.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <future>
#include <mutex>
#include <numbers>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/core/toml_reader.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/face_mesh.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/interp/program.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/curve_file.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/tool_table.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::io {
namespace {

// G1 corner smoothing: the keys of a G-code [path] and of [compare].
void ReadCornerOptions(TomlTable& t, geometry::CornerOptions* c) {
  if (auto e = t.OptionalPositiveNumber("contour_tol_mm")) c->contour_tol_mm = *e;
  if (auto e = t.OptionalPositiveNumber("orientation_tol_mm")) c->orientation_tol_mm = *e;
  if (auto h = t.OptionalPositiveNumber("top_height_mm")) c->top_height_mm = *h;
  if (auto p = t.OptionalChoice("top_parametrization",
                                {"c2", "bottom_parameter", "uniform", "top_arc_length"})) {
    using T = geometry::TopParametrization;
    c->top = *p == "c2"                 ? T::kC2
             : *p == "bottom_parameter" ? T::kBottomParameter
             : *p == "uniform"          ? T::kUniform
                                        : T::kTopArcLength;
  }
}

void ReadCompare(TomlTable& root, Job* job) {
  auto t = root.OptionalTable("compare");
  if (!t) return;
  if (!job->surface)
    root.Fail("compare", "only surface jobs ([surface]) are compared with exports");
  CompareSpec& c = job->compare;
  for (auto [key, tolerances] : {std::pair{"g1_tolerances_mm", &c.g1_tolerances_mm},
                                 std::pair{"bspline_tolerances_mm", &c.bspline_tolerances_mm}}) {
    if (!t->Has(key)) continue;
    *tolerances = t->Numbers(key);
    for (double v : *tolerances) {
      if (!(v > 0.0)) t->Fail(key, fmt::format("expected tolerances > 0 mm, got {}", v));
    }
  }
  if (auto o = t->OptionalPositiveNumber("orientation_tol_deg")) {
    if (!(*o < 45.0)) t->Fail("orientation_tol_deg", fmt::format("expected < 45 deg, got {}", *o));
    c.orientation_tol_deg = *o;
  }
  if (auto s = t->OptionalPositiveNumber("sample_step_mm")) c.sample_step_mm = *s;
  ReadCornerOptions(*t, &c.corners);
  t->RejectUnknown();
}

// Where a G-code program starts and the offsets it starts with, as LinuxCNC holds them: the
// machine's position (`from`), its parameter file (`parameters`) and work offsets given in the job
// ([path.work_offsets], over the file's).
void ReadGcodeStart(TomlTable& path, const std::string& job_file, GcodeOptions* gcode) {
  if (path.Has("from")) {
    gcode->from = path.Numbers("from");
    if (gcode->from.size() < 3 || gcode->from.size() > 6) {
      path.Fail("from", fmt::format("expected where the machine is, [X, Y, Z] (mm) or with its "
                                    "rotary axes (degrees), got {} values",
                                    gcode->from.size()));
    }
  }
  if (auto file = path.OptionalString("parameters")) {
    gcode->parameters = ReadParameterFile(ResolveRelative(job_file, *file));
  }
  if (auto offsets = path.OptionalTable("work_offsets")) {
    for (const std::string& key : offsets->Keys()) {
      int system = 0;
      for (int n = 1; n <= 9; ++n) {
        if (key == CoordinateSystemName(n)) system = n;
      }
      if (system == 0) {
        offsets->Fail(key, "expected a coordinate system, G54 to G59 or \"G59.1\" to \"G59.3\"");
      }
      const std::vector<double> v = offsets->Numbers(key);
      if (v.size() != 3 && v.size() != 6) {
        offsets->Fail(key, fmt::format("expected [X, Y, Z] (mm) or [X, Y, Z, A, B, C] (mm, "
                                       "degrees), got {} values",
                                       v.size()));
      }
      for (std::size_t k = 0; k < 6; ++k) {
        gcode->parameters[WorkOffsetParameter(system) + static_cast<int>(k)] =
            k < v.size() ? v[k] : 0.0;
      }
    }
    offsets->RejectUnknown();
  }
}

void ReadPath(TomlTable& root, Job* out) {
  Job& job = *out;
  TomlTable path = root.Table("path");
  const std::string kind = path.Choice("kind", {"line", "curve", "gcode"});
  if (kind == "gcode") {
    job.path.kind = PathSpec::Kind::kGcode;
    job.path.gcode_file = ResolveRelative(job.file, path.String("file"));
    if (path.Has("interpreter")) {
      job.path.gcode.interpreter = path.Choice("interpreter", {"rs274ngc", "dtis"}) == "dtis"
                                       ? GcodeInterpreter::kDtis
                                       : GcodeInterpreter::kRs274ngc;
    }
    if (auto table = path.OptionalString("tool_table")) {
      if (job.path.gcode.interpreter != GcodeInterpreter::kRs274ngc) {
        path.Fail("tool_table",
                  "tool length offsets are applied by LinuxCNC's interpreter "
                  "(interpreter = \"rs274ngc\"); dtis' own reader plans the "
                  "programmed tip");
      }
      job.path.gcode.tool_table =
          std::make_shared<const ToolTable>(LoadToolTable(ResolveRelative(job.file, *table)));
    }
    ReadCornerOptions(path, &job.path.gcode.corners);
    if (auto r = path.OptionalPositiveNumber("rapid_feed_mm_min")) {
      job.path.gcode.rapid_feed_mm_s = *r / 60.0;
    }
    if (auto b = path.OptionalBoolean("blend_rapids")) job.path.gcode.blend_rapids = *b;
    if (auto m = path.OptionalInteger("max_blocks")) {
      if (*m < 0) {
        path.Fail("max_blocks", fmt::format("expected 0 (no limit) or more blocks, got {}", *m));
      }
      job.path.gcode.max_blocks = static_cast<long>(*m);
    }
    if (auto w = path.OptionalInteger("window_blocks")) {
      if (*w < 0) path.Fail("window_blocks", fmt::format("expected 0 or more blocks, got {}", *w));
      job.path.gcode.window_blocks = static_cast<std::size_t>(*w);
    }
    if (path.Has("tool_axis")) path.Fail("tool_axis", "a G-code program sets its own tool axis");
    ReadGcodeStart(path, job.file, &job.path.gcode);
    path.RejectUnknown();
    return;
  }
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
}

double Degrees(double deg) { return deg * std::numbers::pi / 180.0; }

Eigen::Vector3d UnitVector(TomlTable& t, std::string_view key) {
  const Eigen::Vector3d v = t.Point(key);
  if (!(v.norm() > 0.0)) t.Fail(key, "expected a non-zero vector");
  return v.normalized();
}

// Faces by number or name (a number, a name, or a list of them), if `key` is there.
std::optional<std::vector<FaceRef>> ReadFaceRefs(TomlTable& table, std::string_view key) {
  const auto given = table.OptionalIndicesOrNames(key);
  if (!given) return std::nullopt;
  std::vector<FaceRef> faces;
  for (const IndexOrName& f : *given) {
    if (f.name.empty() && (f.index < 1 || f.index > std::numeric_limits<int>::max())) {
      table.Fail(key, fmt::format("expected a face number from 1 to {} or a face name, got {}",
                                  std::numeric_limits<int>::max(), f.index));
    }
    faces.push_back({static_cast<int>(f.index), f.name});
  }
  return faces;
}

SurfaceSpec ReadSurface(TomlTable& root, const std::string& file) {
  SurfaceSpec spec;
  TomlTable surface = root.Table("surface");
  spec.step_file = ResolveRelative(file, surface.String("file"));
  if (auto faces = ReadFaceRefs(surface, "face")) spec.faces = std::move(*faces);
  spec.faces_key =
      fmt::format("{}:{}: key '{}'", file, surface.Line("face"), surface.KeyPath("face"));
  if (auto check = ReadFaceRefs(surface, "check_faces")) {
    const bool word = check->size() == 1 && check->front().index == 0;
    if (word && check->front().name == "none") {
      spec.check_faces.emplace();
    } else if (!(word && check->front().name == "others")) {
      spec.check_faces = std::move(*check);
    }
  }
  spec.check_faces_key = fmt::format("{}:{}: key '{}'", file, surface.Line("check_faces"),
                                     surface.KeyPath("check_faces"));
  if (auto t = surface.OptionalNumber("check_tolerance_mm")) {
    if (!(*t >= 0.0)) surface.Fail("check_tolerance_mm", "expected a number of mm >= 0");
    spec.check_tolerance_mm = *t;
  }
  if (auto r = surface.OptionalPoint("rotate_deg")) spec.rotate_deg = *r;
  if (auto t = surface.OptionalPoint("translate_mm")) spec.translate_mm = *t;
  const auto side = surface.OptionalChoice("side", {"auto", "face", "reversed"}).value_or("auto");
  using Spec = strategies::StrategySpec;
  spec.strategy.side = side == "auto"   ? Spec::Side::kAuto
                       : side == "face" ? Spec::Side::kFace
                                        : Spec::Side::kReversed;
  surface.RejectUnknown();

  TomlTable tool = root.Table("tool");
  const auto kind = tool.Choice("kind", {"ball_end", "bull_nose", "flat_end"});
  spec.tool.radius = tool.PositiveNumber("radius_mm");
  if (auto l = tool.OptionalPositiveNumber("length_mm")) spec.tool_length_mm = *l;
  if (kind == "ball_end") {
    spec.tool.kind = geometry::Tool::Kind::kBallEnd;
    spec.tool.corner_radius = spec.tool.radius;
  } else if (kind == "flat_end") {
    spec.tool.kind = geometry::Tool::Kind::kFlatEnd;
  } else {
    spec.tool.kind = geometry::Tool::Kind::kBullNose;
    spec.tool.corner_radius = tool.PositiveNumber("corner_radius_mm");
    if (!(spec.tool.corner_radius < spec.tool.radius)) {
      tool.Fail("corner_radius_mm", fmt::format("expected less than radius_mm ({}), got {}",
                                                spec.tool.radius, spec.tool.corner_radius));
    }
  }
  tool.RejectUnknown();

  if (auto o = root.OptionalTable("orientation")) {
    const auto k = o->Choice("kind", {"fixed", "tilt_yaw"});
    if (k == "fixed") {
      spec.orientation.kind = strategies::Orientation::Kind::kFixed;
      if (o->Has("axis")) spec.orientation.axis = UnitVector(*o, "axis");
      if (o->Has("axis_tolerance_deg")) {
        o->Fail("axis_tolerance_deg",
                "applies to kind = \"tilt_yaw\" (a fixed axis has nothing to smooth)");
      }
    } else {
      spec.orientation.kind = strategies::Orientation::Kind::kTiltYaw;
      const double tilt = o->OptionalNumber("tilt_deg").value_or(0.0);
      const double yaw = o->OptionalNumber("yaw_deg").value_or(0.0);
      if (!(std::abs(tilt) < 90.0)) {
        o->Fail("tilt_deg", fmt::format("expected an angle in (-90, 90) degrees, got {}", tilt));
      }
      spec.orientation.tilt_rad = Degrees(tilt);
      spec.orientation.yaw_rad = Degrees(yaw);
      const double tol = o->OptionalNumber("axis_tolerance_deg").value_or(0.0);
      if (!(tol >= 0.0 && tol <= 5.0)) {
        o->Fail(
            "axis_tolerance_deg",
            fmt::format("expected an angle in [0, 5] degrees (0: the rule's axis), got {}", tol));
      }
      spec.orientation.axis_tolerance_rad = Degrees(tol);
    }
    o->RejectUnknown();
  }

  TomlTable st = root.Table("strategy");
  const auto sk = st.Choice("kind", {"plane_cl", "plane_cc", "uv", "leading_line"});
  Spec& s = spec.strategy;
  s.kind = sk == "plane_cl"   ? Spec::Kind::kPlaneCl
           : sk == "plane_cc" ? Spec::Kind::kPlaneCc
           : sk == "uv"       ? Spec::Kind::kUv
                              : Spec::Kind::kLeadingLine;
  if (s.kind != Spec::Kind::kLeadingLine && st.Has("guide")) {
    st.Fail("guide", "only used by kind = \"leading_line\"");
  }
  if (s.kind == Spec::Kind::kLeadingLine) {
    for (const char* key : {"plane_normal", "direction", "along"}) {
      if (st.Has(key)) st.Fail(key, "not used by kind = \"leading_line\" (it follows its guide)");
    }
    const std::string guide = ResolveRelative(file, st.String("guide"));
    CurveFile curve = LoadCurveFile(guide);
    if (curve.top) st.Fail("guide", "expected a single curve (no [top] curve)");
    s.guide = std::make_shared<const geometry::BSplineCurve>(std::move(curve.bottom));
  } else if (s.kind == Spec::Kind::kUv) {
    for (const char* key : {"plane_normal", "direction"}) {
      if (st.Has(key)) st.Fail(key, "only used by the plane strategies");
    }
    s.along_u = st.OptionalChoice("along", {"u", "v"}).value_or("u") == "u";
  } else {
    if (st.Has("along")) st.Fail("along", "only used by kind = \"uv\"");
    s.plane_normal = UnitVector(st, "plane_normal");
    s.direction = UnitVector(st, "direction");
    s.direction -= s.plane_normal * s.direction.dot(s.plane_normal);
    if (!(s.direction.norm() > 1e-6)) {
      st.Fail("direction", "expected a direction of travel not along plane_normal");
    }
    s.direction.normalize();
  }
  const auto mode = st.OptionalChoice("pathmode", {"forward", "zigzag"}).value_or("forward");
  s.mode = mode == "forward" ? Spec::PathMode::kForward : Spec::PathMode::kZigzag;
  const auto stepover = st.OptionalPositiveNumber("stepover_mm");
  const auto scallop = st.OptionalPositiveNumber("scallop_mm");
  if (stepover.has_value() == scallop.has_value()) {
    st.Fail(stepover ? "scallop_mm" : "stepover_mm",
            "expected exactly one of stepover_mm and scallop_mm");
  }
  s.stepover_mm = stepover.value_or(0.0);
  s.scallop_mm = scallop.value_or(0.0);
  const auto key = [&](std::string_view k) {
    return fmt::format("{}:{}: key '{}'", file, st.Line(k), st.KeyPath(k));
  };
  s.stepover_key = key(stepover ? "stepover_mm" : "scallop_mm");
  if (st.Has("range")) {
    const std::vector<double> r = st.Numbers("range");
    if (r.size() != 2 || !(r[0] <= r[1])) {
      st.Fail("range", "expected [first, last] with first <= last");
    }
    s.range = std::array<double, 2>{r[0], r[1]};
    s.range_key = key("range");
  }
  const auto bounds_min = st.OptionalPoint("bounds_min_mm");
  const auto bounds_max = st.OptionalPoint("bounds_max_mm");
  if (bounds_min || bounds_max) {
    s.bounds = {bounds_min.value_or(Eigen::Vector3d::Constant(-INFINITY)),
                bounds_max.value_or(Eigen::Vector3d::Constant(INFINITY))};
    if (!(s.bounds->min.array() < s.bounds->max.array()).all()) {
      st.Fail(bounds_max ? "bounds_max_mm" : "bounds_min_mm",
              fmt::format("expected bounds_min_mm below bounds_max_mm in x, y and z, got ({}, {}, "
                          "{}) to ({}, {}, {})",
                          s.bounds->min.x(), s.bounds->min.y(), s.bounds->min.z(),
                          s.bounds->max.x(), s.bounds->max.y(), s.bounds->max.z()));
    }
  }
  if (auto m = st.OptionalInteger("max_passes")) {
    if (*m < 1 || *m > std::numeric_limits<int>::max()) {
      st.Fail("max_passes",
              fmt::format("expected 1 to {}, got {}", std::numeric_limits<int>::max(), *m));
    }
    s.max_passes = static_cast<int>(*m);
  }
  if (auto t = st.OptionalPositiveNumber("newton_tol_mm")) s.newton.tolerance_mm = *t;
  s.on_gouge = st.OptionalChoice("on_gouge", {"skip", "stop"}).value_or("skip") == "skip"
                   ? Spec::OnGouge::kSkip
                   : Spec::OnGouge::kStop;
  st.RejectUnknown();
  try {
    if (s.scallop_mm > 0.0)
      strategies::StepoverFromScallop(spec.tool, spec.orientation, s.scallop_mm);
  } catch (const Error& e) {
    st.Fail("scallop_mm", e.what());
  }

  if (auto link = root.OptionalTable("link")) {
    if (auto c = link->OptionalNumber("clearance_mm")) {
      if (!(*c >= 0.0)) link->Fail("clearance_mm", "expected a number of mm >= 0");
      spec.clearance_mm = *c;
    }
    if (auto f = link->OptionalPositiveNumber("feed_mm_min")) spec.link_feed_mm_s = *f / 60.0;
    link->RejectUnknown();
  }
  return spec;
}

// The name places the outputs a job does not name (NAME.csv): inside the current folder, as
// [output] paths are, and never empty (".csv").
void CheckJobName(TomlTable& root, const std::string& name) {
  const std::filesystem::path p(name);
  bool up = false;
  for (const auto& part : p) up = up || part == "..";
  if (name.empty() || p.is_absolute() || up || !p.has_filename()) {
    root.Fail("name", fmt::format("expected a name for the outputs (NAME.csv) inside the current "
                                  "folder (not empty, not absolute, no '..'), got '{}'",
                                  name));
  }
}

Job ReadJob(TomlTable& root) {
  Job job;
  job.file = root.File();
  job.name = root.OptionalString("name").value_or(std::filesystem::path(job.file).stem().string());
  if (root.Has("name")) CheckJobName(root, job.name);
  job.machine_file = ResolveRelative(job.file, root.String("machine"));
  if (auto t = root.OptionalPositiveNumber("machine_jerk_time_ms")) {
    if (!kinematics::IsLinuxcncIni(job.machine_file)) {
      root.Fail("machine_jerk_time_ms",
                "only used with a LinuxCNC INI machine; a machine file states every jerk");
    }
    using Load = kinematics::MachineLoadOptions;
    if (!(*t * 1e-3 >= Load::kMinJerkTimeS && *t * 1e-3 <= Load::kMaxJerkTimeS)) {
      root.Fail("machine_jerk_time_ms",
                fmt::format("expected a time from {:g} to {:g} ms, got {:g}",
                            Load::kMinJerkTimeS * 1e3, Load::kMaxJerkTimeS * 1e3, *t));
    }
    job.machine_options.jerk_time_s = *t * 1e-3;
  }
  const double period_ms = root.OptionalPositiveNumber("period_ms").value_or(1.0);
  if (period_ms < kMinPeriodMs || period_ms > kMaxPeriodMs) {
    root.Fail("period_ms", fmt::format("expected a period from {} to {} ms, got {}", kMinPeriodMs,
                                       kMaxPeriodMs, period_ms));
  }
  job.vpop.period_s = period_ms * 1e-3;
  const std::optional<double> feed = root.OptionalPositiveNumber("feed_mm_min");
  if (root.Has("surface")) {
    if (root.Has("path")) root.Fail("path", "a job has either [path] or [surface], not both");
    job.surface = ReadSurface(root, job.file);
  } else {
    ReadPath(root, &job);
  }
  if (job.path.kind == PathSpec::Kind::kGcode && !job.surface) {
    // The program's F words rule; feed_mm_min, if given, caps them (a feed override).
    if (feed) job.path.gcode.max_feed_mm_s = *feed / 60.0;
    job.vpop.feed_mm_s = 1.0;  // per segment; this only satisfies the options' check
  } else {
    job.vpop.feed_mm_s = (feed ? *feed : root.PositiveNumber("feed_mm_min")) / 60.0;
  }

  ReadCompare(root, &job);

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
    if (auto pl = in->OptionalChoice("planner", {"lookahead", "vpop", "least-time"})) {
      if (job.interpolator != InterpolatorKind::kVpop) {
        in->Fail("planner", "only used by kind = \"vpop\"");
      }
      job.vpop.planner = *interp::PlannerFromName(*pl);
    }
    if (auto b = in->OptionalBoolean("least_time_no_added_chatter")) {
      job.vpop.least_time.no_added_chatter = *b;
    }
    if (auto f = in->OptionalPositiveNumber("limit_fraction")) {
      if (*f > 1.0)
        in->Fail("limit_fraction", fmt::format("expected a number in (0, 1], got {}", *f));
      job.vpop.limit_fraction = *f;
    }
    if (auto e = in->OptionalPositiveNumber("end_tolerance_mm")) {
      // A motion that may end this far from the path's end could skip the path altogether.
      if (*e > kMaxEndToleranceMm) {
        in->Fail("end_tolerance_mm", fmt::format("expected a distance up to {:g} mm, got {:g}",
                                                 kMaxEndToleranceMm, *e));
      }
      job.vpop.end_tolerance_mm = *e;
    }
    if (auto h = in->OptionalInteger("commit_horizon")) {
      if (*h < 8 || *h > kMaxCommitHorizon) {
        in->Fail("commit_horizon",
                 fmt::format("expected 8 to {} periods (2^30), got {}", kMaxCommitHorizon, *h));
      }
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
    // A job names outputs inside the current folder: a job file from elsewhere never writes over
    // files outside it (the command line's -o may name any path).
    const auto inside = [&](std::string_view key) -> std::string {
      const std::string path = out->OptionalString(key).value_or("");
      const std::filesystem::path p(path);
      bool up = false;
      for (const auto& part : p) up = up || part == "..";
      if (p.is_absolute() || up) {
        out->Fail(key, fmt::format("expected a path inside the current folder (not absolute, no "
                                   "'..'), got '{}'; use -o for any other place",
                                   path));
      }
      return path;
    };
    job.setpoints_out = inside("setpoints");
    job.limiters_out = inside("limiters");
    out->RejectUnknown();
  }
  root.RejectUnknown();
  std::string why;
  if (!job.vpop.IsValid(&why)) throw Error("{}: {}", job.file, why);
  return job;
}

// A G-code program, a STEP part or a setpoint file handed where a job is expected gets told what
// to do with it instead of a TOML syntax error on its first line.
void RejectWhatIsNotAJob(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const std::string name = std::filesystem::path(path).filename().string();
  if (ext == ".ngc" || ext == ".nc" || ext == ".gcode" || ext == ".tap" || ext == ".cnc") {
    throw Error(
        "{}: a job file (TOML) is expected, and this looks like a G-code program; plan it with a "
        "job that names it and a machine: machine = \"MACHINE.toml\", [path] kind = \"gcode\", "
        "file = \"{}\" (see samples/jobs/lock.toml and docs/jobs.md)",
        path, name);
  }
  if (ext == ".stp" || ext == ".step" || ext == ".p21") {
    throw Error(
        "{}: a job file (TOML) is expected, and this looks like a STEP part; list its faces with "
        "'dtis faces {}' and name one in a surface job's [surface] (see "
        "samples/jobs/surface_tilt10_xyzac.toml and docs/jobs.md)",
        path, path);
  }
  if (ext == ".csv") {
    throw Error(
        "{}: a job file (TOML) is expected, and this looks like a setpoint file; check it with "
        "'dtis verify {} MACHINE' or draw it with 'dtis report {} MACHINE'",
        path, path, path);
  }
}

}  // namespace

Job ParseJob(std::string_view text, const std::string& source_name) {
  TomlTable root = TomlTable::ParseString(text, source_name);
  return ReadJob(root);
}

void CheckPeriod(const Job& job, const Machine& machine) {
  const double dt = job.vpop.period_s, f = job.vpop.limit_fraction;
  static constexpr const char* kWhat[] = {"velocity", "acceleration", "jerk"};
  for (const Axis& a : machine.Axes()) {
    const std::array<double, 3> at = interp::ShortestPeriods(a, job.vpop);
    const auto k = static_cast<std::size_t>(std::max_element(at.begin(), at.end()) - at.begin());
    if (!(at[k] > dt * (1.0 + 1e-9))) continue;
    const double limit = std::array{a.vmax, a.amax, a.jmax}[k];
    const std::string unit = fmt::format("{}/s{}", a.rotary ? "rad" : "mm",
                                         k == 0   ? ""
                                         : k == 1 ? "^2"
                                                  : "^3");
    const std::string why = fmt::format(
        "rounding the written positions of axis {} (near {:g} {}) would eat more than 0.1 % of "
        "its {} limit ({:g} {}{})",
        a.name, interp::PositionScale(a, job.vpop), a.rotary ? "rad" : "mm", kWhat[k], limit, unit,
        f < 1.0 ? fmt::format(" times limit_fraction {:g}", f) : "");
    interp::VpopOptions whole = job.vpop;
    whole.limit_fraction = 1.0;
    const std::array<double, 3> full = interp::ShortestPeriods(a, whole);
    if (f < 1.0 && *std::max_element(full.begin(), full.end()) <= dt) {
      // limit_fraction scales every guard term by 1/f, 1/f and 1/f: the least f that fits.
      double least = 0.0;
      for (std::size_t i = 0; i < at.size(); ++i) {
        least = std::max(least, f * std::pow(at[i] / dt, static_cast<double>(i + 1)));
      }
      throw Error(
          "{}: [interpolator] limit_fraction = {:g}: at period_ms = {:g} {}; expected a "
          "limit_fraction of at least {:.3g}",
          job.file, f, dt * 1e3, why, least);
    }
    if (at[k] <= kMaxPeriodMs * 1e-3) {
      throw Error(
          "{}: period_ms = {:g} is shorter than machine '{}' allows: {}; expected "
          "period_ms of at least {:.3g}",
          job.file, dt * 1e3, machine.Name(), why, at[k] * 1e3 * (1.0 + 1e-6));
    }
    throw Error(
        "{}: axis {}'s {} limit ({:g} {}) is too small to plan at any period up to {:g} "
        "ms: {}; check {}",
        job.machine_file, a.name, kWhat[k], limit, unit, kMaxPeriodMs, why,
        kinematics::IsLinuxcncIni(job.machine_file)
            ? fmt::format("[AXIS_{}] and its joint's MAX_{}", a.name,
                          std::array{"VELOCITY", "ACCELERATION", "JERK"}[k])
            : fmt::format("key 'axes.{}.{}'", a.name, kWhat[k]));
  }
}

std::unique_ptr<Machine> LoadJobMachine(const Job& job) {
  auto machine = kinematics::LoadMachineFile(job.machine_file, job.machine_options);
  CheckPeriod(job, *machine);
  return machine;
}

Job LoadJob(const std::string& path) {
  RejectWhatIsNotAJob(path);
  TomlTable root = TomlTable::ParseFile(path);
  return ReadJob(root);
}

std::unique_ptr<PathSource> BuildPath(const Job& job) {
  if (job.surface) throw Error("{}: a surface job has several paths (passes)", job.file);
  if (job.path.kind == PathSpec::Kind::kGcode) {
    throw Error("{}: a G-code job has several paths (one per contour)", job.file);
  }
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

namespace {

// Turns what the planners report into RunProgress for RunOptions::progress: the share of a phase's
// path length planned (summed over segments planned in parallel) and the motion time planned, at
// most 20 times a second while planning, and once at each phase's start and segment's end.
class ProgressMeter {
 public:
  explicit ProgressMeter(const RunOptions& options) : report_(options.progress) {}

  // A phase measured by nothing but its name.
  void Phase(std::string_view phase) {
    if (!report_) return;
    std::lock_guard lock(mutex_);
    report_({phase, -1.0, base_motion_s_, 0, 0});
  }

  // A planning phase over segments of these lengths (mm; 0 where not known); motion time counts on
  // from what earlier phases planned.
  void Plan(std::string_view phase, const std::vector<double>& lengths) {
    if (!report_) return;
    std::lock_guard lock(mutex_);
    base_motion_s_ += PlannedMotion();
    phase_ = phase;
    total_mm_ = 0.0;
    for (double l : lengths) total_mm_ += l;
    lengths_ = lengths;
    s_ = std::vector<std::atomic<double>>(lengths.size());
    t_ = std::vector<std::atomic<double>>(lengths.size());
    done_ = 0;
    ReportLocked();
  }

  // interp::ProgramOptions::advance and ::progress for the phase Plan began.
  std::function<void(int, double, double)> Advance() {
    if (!report_) return {};
    return [this](int segment, double s, double t) {
      // One thread plans a segment; a back-off may take some of it back: show the furthest.
      const auto k = static_cast<std::size_t>(segment);
      if (s > s_[k].load(std::memory_order_relaxed)) s_[k].store(s, std::memory_order_relaxed);
      if (t > t_[k].load(std::memory_order_relaxed)) t_[k].store(t, std::memory_order_relaxed);
      std::unique_lock lock(mutex_, std::try_to_lock);
      if (!lock) return;  // another thread is reporting: this news goes with the next report
      const auto now = std::chrono::steady_clock::now();
      if (now - last_ < std::chrono::milliseconds(50)) return;
      last_ = now;
      ReportLocked();
    };
  }
  std::function<void(int, int)> Finished() {
    if (!report_) return {};
    return [this](int done, int) {
      std::lock_guard lock(mutex_);
      done_ = std::max(done_, done);
      ReportLocked();
    };
  }

 private:
  double PlannedMotion() const {
    double t = 0.0;
    for (const auto& x : t_) t += x.load(std::memory_order_relaxed);
    return t;
  }
  void ReportLocked() {
    double s = 0.0;
    for (std::size_t k = 0; k < s_.size(); ++k) {
      s += std::min(lengths_[k], s_[k].load(std::memory_order_relaxed));
    }
    const int n = static_cast<int>(lengths_.size());
    const double fraction = total_mm_ > 0.0 ? s / total_mm_
                            : n > 0         ? static_cast<double>(done_) / n
                                            : 0.0;
    report_({phase_, std::clamp(fraction, 0.0, 1.0), base_motion_s_ + PlannedMotion(), done_, n});
  }

  std::function<void(const RunProgress&)> report_;
  std::mutex mutex_;
  std::string_view phase_;
  std::vector<double> lengths_;
  double total_mm_ = 0.0;
  std::vector<std::atomic<double>> s_, t_;
  int done_ = 0;
  double base_motion_s_ = 0.0;
  std::chrono::steady_clock::time_point last_{};
};

// Each segment's path length (0 where it is not known), for ProgressMeter::Plan.
std::vector<double> Lengths(const std::vector<interp::ProgramSegment>& segments) {
  std::vector<double> lengths;
  for (const auto& seg : segments) lengths.push_back(seg.path->Length().value_or(0.0));
  return lengths;
}

std::string Describe(const FaceRef& f) {
  return f.name.empty() ? std::to_string(f.index) : fmt::format("'{}'", f.name);
}

// Faces of the model, set up on the machine as the job places them, in this order.
std::vector<geometry::NamedFace> Placed(const SurfaceSpec& spec, const geometry::StepModel& model,
                                        const std::vector<int>& indices) {
  std::vector<geometry::NamedFace> faces;
  for (const int k : indices) {
    const std::string& name = model.FaceName(k);
    faces.push_back({geometry::PlaceFace(model.Face(k), spec.rotate_deg, spec.translate_mm),
                     name.empty() ? fmt::format("{} face {}", spec.step_file, k)
                                  : fmt::format("{} face {} ('{}')", spec.step_file, k, name)});
  }
  return faces;
}

// The job's faces, placed.
std::vector<geometry::NamedFace> PlacedFaces(const SurfaceSpec& spec) {
  const geometry::StepModel model = geometry::StepModel::Load(spec.step_file);
  return Placed(spec, model, JobFaces(spec, model));
}

// The faces `refs` name in the model, in their order; `key` says where they were given.
std::vector<int> ResolveFaces(const std::vector<FaceRef>& refs, const std::string& key,
                              const SurfaceSpec& spec, const geometry::StepModel& model) {
  std::vector<int> faces;
  std::vector<std::string> given;  // how each was given, for "listed twice"
  const auto add = [&](int k, const FaceRef& ref) {
    const auto at = std::find(faces.begin(), faces.end(), k);
    if (at != faces.end()) {
      throw Error("{}: face {} of {} is given twice (as {} and {})", key, k, spec.step_file,
                  given[static_cast<std::size_t>(at - faces.begin())], Describe(ref));
    }
    faces.push_back(k);
    given.push_back(Describe(ref));
  };
  for (const FaceRef& ref : refs) {
    if (ref.name.empty()) {
      if (ref.index > model.FaceCount()) {
        throw Error("{}: face {} does not exist; {} has faces 1 to {} (`dtis faces` lists them)",
                    key, ref.index, spec.step_file, model.FaceCount());
      }
      add(ref.index, ref);
      continue;
    }
    std::vector<int> named = model.FacesNamed(ref.name);
    // "name#N": the N-th face of that name, in the file's order (when no face is named so whole).
    const std::size_t hash = ref.name.rfind('#');
    if (named.empty() && hash != std::string::npos && hash > 0 && hash + 1 < ref.name.size() &&
        ref.name.find_first_not_of("0123456789", hash + 1) == std::string::npos) {
      const std::string base = ref.name.substr(0, hash);
      const std::vector<int> all_named = model.FacesNamed(base);
      if (!all_named.empty()) {
        const std::string digits = ref.name.substr(hash + 1);
        const std::size_t nth = digits.size() > 9 ? 0 : std::stoul(digits);
        if (nth < 1 || nth > all_named.size()) {
          throw Error(
              "{}: {} has {} face{} named '{}' ('{}#1' to '{}#{}', in the file's order); "
              "there is no '{}'",
              key, spec.step_file, all_named.size(), all_named.size() == 1 ? "" : "s", base, base,
              base, all_named.size(), ref.name);
        }
        named = {all_named[nth - 1]};
      }
    }
    if (named.empty()) {
      std::vector<std::string> names;
      for (int k = 1; k <= model.FaceCount(); ++k) {
        const std::string& n = model.FaceName(k);
        if (!n.empty() && names.size() < 12) names.push_back(fmt::format("'{}' ({})", n, k));
      }
      throw Error("{}: {} has no face named '{}'; {}", key, spec.step_file, ref.name,
                  names.empty() ? fmt::format("it names none of its {} faces: give their numbers "
                                              "(`dtis faces {}`)",
                                              model.FaceCount(), spec.step_file)
                                : fmt::format("its named faces: {}", fmt::join(names, ", ")));
    }
    for (const int k : named) add(k, ref);
  }
  return faces;
}

// The faces the tool must not go into besides the job's (`finished`): check_faces. Throws
// dtis::Error naming the key for a face the job also finishes.
std::vector<int> CheckFaceIndices(const SurfaceSpec& spec, const geometry::StepModel& model,
                                  const std::vector<int>& finished) {
  const auto is_finished = [&](int k) {
    return std::find(finished.begin(), finished.end(), k) != finished.end();
  };
  std::vector<int> check;
  if (!spec.check_faces) {
    for (int k = 1; k <= model.FaceCount(); ++k) {
      if (!is_finished(k)) check.push_back(k);
    }
    return check;
  }
  check = ResolveFaces(*spec.check_faces, spec.check_faces_key, spec, model);
  for (const int k : check) {
    if (is_finished(k)) {
      throw Error("{}: face {} of {} is finished by the job ({}); check the faces besides it",
                  spec.check_faces_key, k, spec.step_file, DescribeFaces(spec));
    }
  }
  return check;
}

}  // namespace

std::vector<int> JobFaces(const SurfaceSpec& spec, const geometry::StepModel& model) {
  return ResolveFaces(spec.faces, spec.faces_key, spec, model);
}

std::string FaceRefsText(const SurfaceSpec& spec) {
  std::vector<std::string> parts;
  for (const FaceRef& f : spec.faces) parts.push_back(Describe(f));
  return fmt::format("{}", fmt::join(parts, ", "));
}

std::string DescribeFaces(const SurfaceSpec& spec) {
  return fmt::format("face{} {}", spec.faces.size() == 1 ? "" : "s", FaceRefsText(spec));
}

SurfaceSetup SetUpSurface(const Job& job, const std::function<void(std::string_view)>& phase) {
  const SurfaceSpec& spec = *job.surface;
  if (job.interpolator != InterpolatorKind::kVpop) {
    throw Error("{}: surface jobs run with the VPOp interpolator only", job.file);
  }
  if (phase) phase("reading STEP");
  const geometry::StepModel model = geometry::StepModel::Load(spec.step_file);
  const std::vector<int> finished = JobFaces(spec, model);
  const std::vector<geometry::NamedFace> placed = Placed(spec, model, finished);
  // The job's faces, then the ones it checks besides them: links clear them all, and the tool
  // finishing one face must go into none of the others.
  std::vector<geometry::NamedFace> all = placed;
  for (auto& f : Placed(spec, model, CheckFaceIndices(spec, model, finished))) {
    all.push_back(std::move(f));
  }
  std::optional<geometry::CheckFaces> checks;  // (a face's box costs a millisecond or more)
  if (all.size() > 1) {
    checks.emplace(all, spec.tool, spec.tool_length_mm, spec.check_tolerance_mm);
  }
  SurfaceSetup setup;
  setup.checked_faces = static_cast<int>(all.size() - placed.size());
  setup.job_faces = static_cast<int>(placed.size());
  if (phase) phase("tracing passes");
  // Face after face, each with the whole strategy; their passes and stretches left out in turn.
  for (std::size_t k = 0; k < placed.size(); ++k) {
    strategies::StrategySpec strategy = spec.strategy;
    strategy.bounds_solid = model.BoundsSolid(finished[k]);
    if (checks) strategy.check = std::make_shared<const geometry::CheckFaces>(checks->Without(k));
    const geometry::FaceSurface face(placed[k].face, placed[k].where);
    strategies::PassList one = strategies::BuildPasses(face, spec.tool, spec.orientation, strategy);
    if (k == 0) {
      setup.passes.stepover_mm = one.stepover_mm;
      setup.passes.side = one.side;
    }
    for (auto& pass : one.passes) setup.passes.passes.push_back(std::move(pass));
    for (auto& u : one.unreachable) {
      if (placed.size() > 1) u.face = placed[k].where;
      setup.passes.unreachable.push_back(std::move(u));
    }
  }
  setup.link_heights = std::make_shared<const geometry::LinkHeights>(
      std::move(all), spec.tool.radius, spec.clearance_mm);
  setup.clearance_mm = spec.clearance_mm;
  setup.pass_options = job.vpop;
  setup.link_options = job.vpop;
  if (spec.link_feed_mm_s > 0.0) setup.link_options.feed_mm_s = spec.link_feed_mm_s;
  setup.link_corners = job.compare.corners;
  setup.link_corners.feed_mm_s = setup.link_options.feed_mm_s;
  return setup;
}

void CheckPassesInTravel(const SurfaceSetup& setup, const Machine& machine,
                         const std::string& job_file, double step_mm) {
  const auto out_of_travel = [](const InverseResult& r) {
    return r.status == InverseStatus::kOutOfTravel || r.status == InverseStatus::kUnreachable;
  };
  const auto& passes = setup.passes.passes;
  for (std::size_t k = 0; k < passes.size(); ++k) {
    const strategies::SurfacePass* pass = passes[k].get();
    const double length = pass->Length().value_or(0.0);
    PathState state = pass->Start();
    AxisVector q, previous;
    bool have_previous = false;
    for (double s = 0.0;; s = std::min(s + step_mm, length)) {
      const PathSample sample = pass->At(state, s);
      if (sample.status == PathStatus::kLeftDomain || sample.status == PathStatus::kNoConvergence) {
        break;  // the planner says where and why
      }
      state = sample.state;
      const InverseResult r = machine.Inverse(sample.pose, have_previous ? &previous : nullptr, &q);
      if (out_of_travel(r)) {
        throw Error("{}: pass {}: cannot follow the path at {}: {} (found before planning)",
                    job_file, k + 1, pass->Describe(state), DescribeInverseFailure(machine, r));
      }
      if (r.status == InverseStatus::kOk) {
        previous = q;
        have_previous = true;
      }
      if (s >= length || sample.status == PathStatus::kEnd) break;
    }
  }
  // The links' corners: where each backs off, rises, traverses and comes down.
  for (std::size_t k = 0; k + 1 < passes.size(); ++k) {
    const Pose from = passes[k]->EndPose(), to = passes[k + 1]->StartPose();
    if ((from.tip - to.tip).norm() < 1e-9) continue;
    const double z = setup.link_heights ? setup.link_heights->TraverseZ(from, to)
                                        : std::max(from.tip.z(), to.tip.z()) + setup.clearance_mm;
    const std::vector<Pose> corners = geometry::LinkWaypoints(
        from, to, z, setup.clearance_mm, passes[k + 1]->RidesOverFromPrevious());
    for (std::size_t c = 0; c < corners.size(); ++c) {
      AxisVector q;
      const InverseResult r = machine.Inverse(corners[c], nullptr, &q);
      if (out_of_travel(r)) {
        const Eigen::Vector3d& p = corners[c].tip;
        throw Error(
            "{}: link from pass {} to pass {}: cannot follow it at its corner {} of {}, tip "
            "({:.6g}, {:.6g}, {:.6g}) mm: {} (found before planning)",
            job_file, k + 1, k + 2, c + 1, corners.size(), p.x(), p.y(), p.z(),
            DescribeInverseFailure(machine, r));
      }
    }
  }
}

geometry::FaceMesh MeshJobSurface(const Job& job) {
  if (!job.surface) throw Error("{}: not a surface job: no face to mesh", job.file);
  return geometry::MeshFaces(PlacedFaces(*job.surface));
}

PassProgram PlanPasses(const std::vector<const PathSource*>& passes, const SurfaceSetup& setup,
                       const Machine& machine, const RunOptions& options,
                       const std::string& job_file) {
  const int n = static_cast<int>(passes.size());
  std::vector<interp::ProgramSegment> pass_segments;
  for (int k = 0; k < n; ++k) {
    pass_segments.push_back(
        {passes[static_cast<std::size_t>(k)], setup.pass_options, fmt::format("pass {}", k + 1)});
  }
  // The passes first, in parallel; then the links, from where each pass really ended (its last
  // setpoint) to where the next one starts, so that no position jumps by even a rounding error.
  ProgressMeter meter(options);
  meter.Plan("planning passes", Lengths(pass_segments));
  interp::ProgramOptions po;
  po.threads = options.threads;
  po.progress = meter.Finished();
  po.advance = meter.Advance();
  std::vector<interp::PlannedSegment> planned_passes =
      interp::PlanSegments(pass_segments, machine, po);
  std::vector<std::unique_ptr<PathSource>> links;
  std::vector<interp::ProgramSegment> link_segments;
  std::vector<int> links_after(static_cast<std::size_t>(n), 0);
  for (int k = 0; k + 1 < n; ++k) {
    const auto& done = planned_passes[static_cast<std::size_t>(k)];
    const auto& next = planned_passes[static_cast<std::size_t>(k + 1)];
    if (done.error || next.error || done.rows.empty() || next.rows.empty()) continue;
    const Pose from = machine.Forward(done.rows.back().q);
    const Pose to = machine.Forward(next.rows.front().q);
    std::vector<std::unique_ptr<PathSource>> moves;
    try {
      moves = geometry::LinkMoves(
          from, to, setup.link_heights->TraverseZ(from, to), setup.clearance_mm, machine,
          setup.link_corners,
          setup.passes.passes[static_cast<std::size_t>(k + 1)]->RidesOverFromPrevious());
    } catch (const Error& e) {
      throw Error("{}: linking pass {} to pass {}: {}", job_file, k + 1, k + 2, e.what());
    }
    for (auto& m : moves) {
      link_segments.push_back(
          {m.get(), setup.link_options, fmt::format("link from pass {} to pass {}", k + 1, k + 2)});
      links.push_back(std::move(m));
      ++links_after[static_cast<std::size_t>(k)];
    }
  }
  PassProgram out;
  out.links = static_cast<int>(links.size());
  if (!link_segments.empty()) meter.Plan("planning links", Lengths(link_segments));
  std::vector<interp::PlannedSegment> planned_links =
      interp::PlanSegments(link_segments, machine, po);
  // Interleave: pass 1, its links, pass 2, ...
  std::vector<interp::ProgramSegment> segments;
  std::vector<interp::PlannedSegment> planned;
  std::size_t l = 0;
  for (int k = 0; k < n; ++k) {
    segments.push_back(pass_segments[static_cast<std::size_t>(k)]);
    planned.push_back(std::move(planned_passes[static_cast<std::size_t>(k)]));
    out.pass_of_segment.push_back(k);
    for (int m = 0; m < links_after[static_cast<std::size_t>(k)]; ++m, ++l) {
      segments.push_back(link_segments[l]);
      planned.push_back(std::move(planned_links[l]));
      out.pass_of_segment.push_back(-1);
    }
  }
  try {
    out.program = interp::Stitch(segments, std::move(planned), machine);
  } catch (const Error& e) {
    throw Error("{}: {}", job_file, e.what());
  }
  return out;
}

std::vector<std::pair<long, long>> PassRows(const PassProgram& pp) {
  std::vector<std::pair<long, long>> rows;
  const auto& first = pp.program.first_row;
  for (std::size_t k = 0; k < pp.pass_of_segment.size() && k < first.size(); ++k) {
    if (pp.pass_of_segment[k] < 0) continue;
    const long end =
        k + 1 < first.size() ? first[k + 1] : static_cast<long>(pp.program.setpoints.size());
    rows.emplace_back(first[k], end);
  }
  return rows;
}

namespace {

// Passes and the links between them, planned as one program.
void RunSurface(const Job& job, const RunOptions& options, RunResult* r) {
  ProgressMeter meter(options);
  const SurfaceSetup setup =
      SetUpSurface(job, [&meter](std::string_view phase) { meter.Phase(phase); });
  std::vector<const PathSource*> passes;
  for (const auto& pass : setup.passes.passes) {
    passes.push_back(pass.get());
    r->path_length_mm += *pass->Length();
  }
  r->passes = static_cast<int>(passes.size());
  r->stepover_mm = setup.passes.stepover_mm;
  r->checked_faces = setup.checked_faces;
  r->job_faces = setup.job_faces;
  r->unreachable = setup.passes.UnreachableText(kSummaryUnreachable);
  r->unreachable_all = setup.passes.UnreachableText(setup.passes.unreachable.size());
  r->unreachable_count = setup.passes.unreachable.size();
  CheckRunBound(job, r->path_length_mm);
  meter.Phase("checking travel");
  CheckPassesInTravel(setup, *r->machine, job.file);
  const PassProgram pp = PlanPasses(passes, setup, *r->machine, options, job.file);
  r->links = pp.links;
  TableSink sink(*r->machine, job.vpop.period_s);
  for (const auto& sp : pp.program.setpoints) sink.Accept(sp);
  r->vpop = pp.program.total;
  for (std::size_t k = 0; k < pp.pass_of_segment.size(); ++k) {
    if (pp.pass_of_segment[k] >= 0) r->pass_motion_s += pp.program.segments[k].motion_time_s;
  }
  r->pass_rows = PassRows(pp);
  r->table = sink.Table();
  r->arc_length = sink.ArcLength();
  r->limiters = sink.Limiters();
}

}  // namespace

namespace {

// A G-code program: its contours and rapids planned as one program.
void RunGcode(const Job& job, const RunOptions& options, RunResult* r) {
  if (job.interpolator != InterpolatorKind::kVpop) {
    throw Error("{}: G-code jobs run with the VPOp interpolator only", job.file);
  }
  ProgressMeter meter(options);
  meter.Phase("reading G-code");
  GcodeStart start;
  try {
    start = GcodeStartOf(job.path.gcode, *r->machine);
  } catch (const Error& e) {
    throw Error("{}: [path] {}", job.file, e.what());
  }
  const GcodeProgram program =
      ReadGcode(job.path.gcode_file, job.path.gcode.interpreter, job.path.gcode.tool_table, start,
                JobReadOptions(job.path.gcode, job.file));
  r->blocks = static_cast<int>(program.moves.size());
  r->gcode_notes = program.notes;
  meter.Phase("building contours");
  const GcodePlan plan = BuildGcodePlan(program, *r->machine, job.vpop, job.path.gcode);
  r->chains = plan.chains;
  r->rapids = plan.rapids;
  r->corners = plan.corners;
  r->path_length_mm = plan.length_mm;
  CheckRunBound(job, plan.length_mm, plan.least_time_s);
  meter.Plan("planning", Lengths(plan.segments));
  interp::ProgramOptions po;
  po.threads = options.threads;
  po.progress = meter.Finished();
  po.advance = meter.Advance();
  interp::ProgramResult program_result;
  try {
    program_result = interp::PlanProgram(plan.segments, *r->machine, po);
  } catch (const Error& e) {
    throw Error("{}: {}", job.file, e.what());
  }
  TableSink sink(*r->machine, job.vpop.period_s);
  for (const auto& sp : program_result.setpoints) sink.Accept(sp);
  r->vpop = program_result.total;
  r->table = sink.Table();
  r->arc_length = sink.ArcLength();
  r->limiters = sink.Limiters();
}

}  // namespace

RunResult RunJob(const Job& job, const RunOptions& options) {
  RunResult r;
  r.machine = LoadJobMachine(job);
  ProgressMeter meter(options);
  if (!job.surface && job.path.kind == PathSpec::Kind::kGcode) {
    const auto start = std::chrono::steady_clock::now();
    RunGcode(job, options, &r);
    r.compute_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    meter.Phase("verifying");
    r.verify = interp::Verify(r.table, *r.machine);
    return r;
  }
  if (job.surface) {
    const auto start = std::chrono::steady_clock::now();
    RunSurface(job, options, &r);
    r.compute_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    meter.Phase("verifying");
    r.verify = interp::Verify(r.table, *r.machine);
    return r;
  }
  const auto path = BuildPath(job);
  r.path_length_mm = path->Length().value_or(0.0);
  CheckRunBound(job, r.path_length_mm);
  TableSink sink(*r.machine, job.vpop.period_s);
  const auto start = std::chrono::steady_clock::now();
  meter.Plan("planning", {r.path_length_mm});
  if (job.interpolator == InterpolatorKind::kVpop) {
    try {
      interp::VpopOptions o = job.vpop;
      const auto advance = meter.Advance();
      if (advance) o.progress = [advance](double s, double t) { advance(0, s, t); };
      r.vpop = interp::PlanVpop(*path, *r.machine, o, sink);
      if (advance) {
        advance(0, r.vpop.end_s, r.vpop.motion_time_s);
        meter.Finished()(1, 1);
      }
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
  meter.Phase("verifying");
  r.verify = interp::Verify(r.table, *r.machine);
  return r;
}

// "1 contour", "2 contours".
std::string Count(long n, std::string_view what) {
  return fmt::format("{} {}{}", n, what, n == 1 ? "" : "s");
}

std::string FormatRunSummary(const Job& job, const RunResult& r) {
  // The planner that ran (`--planner` names it so), or the Taylor interpolator.
  const std::string planner = job.interpolator == InterpolatorKind::kVpop
                                  ? fmt::format("{} planner", interp::PlannerName(job.vpop.planner))
                                  : InterpolatorName(job.interpolator);
  std::string out = fmt::format("job {}: {} on machine '{}', path {:.6g} mm\n", job.name, planner,
                                r.machine->Name(), r.path_length_mm);
  if (job.surface) {
    // A name stands for every face the file gives it: say how many faces that made.
    const std::string how_many =
        r.job_faces > static_cast<int>(job.surface->faces.size())
            ? fmt::format(" ({} faces: a name selects every face of that name, 'NAME#N' the N-th)",
                          r.job_faces)
            : "";
    out += fmt::format("surface          {} {}{}, {}, {}, {}\n", job.surface->step_file,
                       DescribeFaces(*job.surface), how_many, job.surface->tool.Describe(),
                       job.surface->orientation.Describe(),
                       strategies::StrategySpec::KindName(job.surface->strategy.kind));
    out += fmt::format(
        "passes           {} (stepover {:.6g} mm), {} link moves, {:.6f} s on the "
        "passes\n",
        r.passes, r.stepover_mm, r.links, r.pass_motion_s);
    std::vector<std::string> checked;
    if (r.checked_faces > 0) {
      checked.push_back(
          fmt::format("the tool kept out of {} face{} of the part besides the job's "
                      "(check_faces)",
                      r.checked_faces, r.checked_faces == 1 ? "" : "s"));
    }
    if (r.job_faces > 1) {
      checked.push_back(fmt::format("each face's passes out of the job's {} other face{}",
                                    r.job_faces - 1, r.job_faces == 2 ? "" : "s"));
    }
    if (!checked.empty()) out += fmt::format("checked          {}\n", fmt::join(checked, "; "));
    if (!r.unreachable.empty()) out += "unreachable      " + r.unreachable;
    if (r.unreachable_count > kSummaryUnreachable) {
      out += "                 (an HTML report, `dtis run --report F.html`, lists them all)\n";
    }
    out += fmt::format("newton           {:.3f} iterations per evaluation ({} evaluations)\n",
                       r.vpop.evaluations ? static_cast<double>(r.vpop.path_iterations) /
                                                static_cast<double>(r.vpop.evaluations)
                                          : 0.0,
                       r.vpop.evaluations);
  }
  if (!job.surface && job.path.kind == PathSpec::Kind::kGcode) {
    out += fmt::format("program          {}: {}, {}, {}, {}\n", job.path.gcode_file,
                       Count(r.blocks, "move"), Count(r.chains, "contour"),
                       Count(r.rapids, "rapid"), Count(r.corners, "smoothed corner"));
    out += fmt::format("interpreter      {}\n", GcodeInterpreterName(job.path.gcode.interpreter));
    if (const auto& tools = job.path.gcode.tool_table) {
      out += fmt::format("tool table       {}: {} tool{}, G43 offsets applied\n", tools->file,
                         tools->tools.size(), tools->tools.size() == 1 ? "" : "s");
    }
    for (const auto& [what, count] : r.gcode_notes) {
      out += fmt::format("                 {} x {}\n", count, what);
    }
  }
  out += fmt::format("motion time      {:.6f} s\n", r.verify.motion_time_s);
  out += fmt::format("setpoints        {} at {:.6g} ms\n", r.verify.rows, job.vpop.period_s * 1e3);
  out += fmt::format("worst ratio      {:.6f} ({}){}\n", r.verify.worst_ratio, r.verify.worst,
                     r.verify.Passed() ? "" : "  ** the verifier FAILS this sequence **");
  const double rt = r.compute_s > 0 ? r.verify.motion_time_s / r.compute_s : 0.0;
  out += fmt::format("compute time     {:.6f} s ({:.3g}x real time)\n", r.compute_s, rt);
  if (job.interpolator == InterpolatorKind::kVpop) {
    if (job.vpop.planner != interp::PlannerKind::kVpop) {
      out +=
          fmt::format("look-ahead       {} grid points, {} repairs, {} refusals\n",
                      r.vpop.profile_grid_points, r.vpop.profile_repairs, r.vpop.profile_refusals);
    }
    if (job.vpop.planner == interp::PlannerKind::kLeastTime) {
      out += fmt::format("least time       {} windows, {} linear programs, {} periods saved\n",
                         r.vpop.least_time_windows, r.vpop.least_time_programs,
                         r.vpop.least_time_saved);
    }
    out += fmt::format("back-offs        {} ({} brake tests), {} evaluations\n", r.vpop.back_offs,
                       r.vpop.brake_tests, r.vpop.evaluations);
    if (r.vpop.stop_proofs > 0) {
      out += fmt::format("stop proofs      {} ({} with the stop law planned blind)\n",
                         r.vpop.stop_proofs, r.vpop.blind_proofs);
    }
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

const char* InterpolatorName(InterpolatorKind kind) {
  switch (kind) {
    case InterpolatorKind::kVpop:
      return "VPOp";
    case InterpolatorKind::kTaylor1:
      return "Taylor order 1";
    case InterpolatorKind::kTaylor2:
      return "Taylor order 2";
  }
  return "?";
}

bool FitToWrite(const Job& job, const RunResult& r) {
  return r.verify.Passed() || job.interpolator != InterpolatorKind::kVpop;
}

std::string UnfitMessage(const Job& job, const RunResult& r) {
  return fmt::format("{}: the verifier fails these setpoints (worst ratio {:.9f}, {})", job.file,
                     r.verify.worst_ratio, r.verify.worst);
}

namespace {

// The least motion time (s) the job's keys allow a path of `length_mm`, with the key that sets
// it: the longest of these bounds is the least time of the motion.
struct LeastTime {
  double s;
  std::string key;
  double value;
};

std::vector<LeastTime> LeastTimes(const Job& job, double length_mm, double program_least_s) {
  std::vector<LeastTime> bounds;
  if (length_mm > 0.0) {
    // A G-code program's F words rule its feed, not feed_mm_min.
    if (job.surface || job.path.kind != PathSpec::Kind::kGcode) {
      bounds.push_back({length_mm / job.vpop.feed_mm_s, "feed_mm_min", job.vpop.feed_mm_s * 60.0});
    }
    const double a = job.vpop.tangential_acceleration_mm_s2, j = job.vpop.tangential_jerk_mm_s3;
    if (std::isfinite(a)) {
      bounds.push_back({2.0 * std::sqrt(length_mm / a), "[tangential] acceleration_mm_s2", a});
    }
    if (std::isfinite(j)) {
      bounds.push_back({std::cbrt(32.0 * length_mm / j), "[tangential] jerk_mm_s3", j});
    }
  }
  // The Taylor interpolators ramp the feed up and down over accel_time_s each.
  if (job.interpolator != InterpolatorKind::kVpop) {
    bounds.push_back(
        {2.0 * job.taylor.accel_time_s, "[interpolator] accel_time_s", job.taylor.accel_time_s});
  }
  if (program_least_s > 0.0) {
    bounds.push_back({program_least_s, "the program's F words, rapids and dwells", NAN});
  }
  return bounds;
}

std::string KeyValue(const LeastTime& b) {
  return std::isnan(b.value) ? b.key : fmt::format("{} = {:g}", b.key, b.value);
}

}  // namespace

void CheckMotionBound(const Job& job, double length_mm, double program_least_s) {
  for (const LeastTime& b : LeastTimes(job, length_mm, program_least_s)) {
    if (b.s <= kMaxMotionHours * 3600.0) continue;
    throw Error(
        "{}: the path ({:.6g} mm) takes at least {:.3g} h with {}, more than the {:g} h a job may "
        "take: check {}",
        job.file, length_mm, b.s / 3600.0, KeyValue(b), kMaxMotionHours, b.key);
  }
}

void CheckRunBound(const Job& job, double length_mm, double program_least_s) {
  CheckMotionBound(job, length_mm, program_least_s);
  for (const LeastTime& b : LeastTimes(job, length_mm, program_least_s)) {
    const double rows = b.s / job.vpop.period_s;
    if (rows <= static_cast<double>(kMaxRunSetpoints)) continue;
    throw Error(
        "{}: the path ({:.6g} mm) takes at least {:.3g} h with {}: {:.3g} setpoints at {:g} ms, "
        "more than the {:g} million `dtis run` holds in memory: check {} and period_ms, or plan "
        "it in constant memory with `dtis stream JOB --to /dev/null --pace none --record FILE`",
        job.file, length_mm, b.s / 3600.0, KeyValue(b), rows, job.vpop.period_s * 1e3,
        static_cast<double>(kMaxRunSetpoints) / 1e6, b.key);
  }
}

void WriteRunOutputs(const Job& job, const RunResult& r, const std::string& setpoints_path,
                     const std::string& limiters_path, bool keep_failed) {
  if (!keep_failed && !FitToWrite(job, r)) {
    throw Error("{}: {} not written", UnfitMessage(job, r), setpoints_path);
  }
  std::optional<AtomicFile> limiters;
  if (!limiters_path.empty()) {
    limiters.emplace(limiters_path);
    limiters->Write(FormatLimiters(r.table, r.arc_length, r.limiters, job.vpop.period_s));
  }
  SetpointWriter setpoints(setpoints_path, r.table.axes);
  WriteSetpointRows(r.table, &setpoints);
  // Both files land together or not at all: the setpoints first, they matter most, unless the
  // limiter report goes to a device or a FIFO, which cannot be taken back.
  CommitTogether({&setpoints.Finish(), limiters ? &*limiters : nullptr});
}

}  // namespace dtis::io
