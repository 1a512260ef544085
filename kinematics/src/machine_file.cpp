// Machine files: TOML with the units stated in the file, converted to mm, s, rad on reading; a
// path ending in .ini is read as a LinuxCNC INI file (linuxcnc_ini.cpp).
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/core/toml_reader.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::kinematics {
namespace {

constexpr double kPi = std::numbers::pi;

struct Units {
  double length = 1.0;  // to mm
  double angle = 1.0;   // to rad
  double linear_velocity = 1.0, linear_acceleration = 1.0, linear_jerk = 1.0;
  double rotary_velocity = 1.0, rotary_acceleration = 1.0, rotary_jerk = 1.0;
};

double Unit(TomlTable& t, std::string_view key, const std::map<std::string, double>& factors) {
  std::vector<std::string> names;
  for (const auto& [name, factor] : factors) names.push_back(name);
  return factors.at(t.Choice(key, names));
}

// The angle and rotary units are required only when the machine has rotary axes; an XYZ machine
// may state them (they are checked) or leave them out. Likewise the linear ones for an arm, whose
// joints are all rotary (its lengths are in `length`).
Units ReadUnits(TomlTable& t, bool rotary_axes, bool linear_axes = true) {
  Units u;
  u.length = Unit(t, "length", {{"mm", 1.0}, {"m", 1000.0}, {"in", 25.4}});
  // A unit only rotary axes use: read when they exist or the file states it, else left at 1.
  const auto rotary = [&](std::string_view key, const std::map<std::string, double>& factors) {
    return rotary_axes || t.Has(key) ? Unit(t, key, factors) : 1.0;
  };
  const auto linear = [&](std::string_view key, const std::map<std::string, double>& factors) {
    return linear_axes || t.Has(key) ? Unit(t, key, factors) : 1.0;
  };
  u.angle = rotary("angle", {{"deg", kPi / 180.0}, {"rad", 1.0}});
  u.linear_velocity = linear("linear_velocity", {{"mm/s", 1.0},
                                                 {"mm/min", 1.0 / 60.0},
                                                 {"m/s", 1000.0},
                                                 {"m/min", 1000.0 / 60.0},
                                                 {"in/s", 25.4},
                                                 {"in/min", 25.4 / 60.0}});
  u.linear_acceleration =
      linear("linear_acceleration", {{"mm/s^2", 1.0}, {"m/s^2", 1000.0}, {"in/s^2", 25.4}});
  u.linear_jerk = linear("linear_jerk", {{"mm/s^3", 1.0}, {"m/s^3", 1000.0}, {"in/s^3", 25.4}});
  u.rotary_velocity = rotary("rotary_velocity", {{"rad/s", 1.0},
                                                 {"deg/s", kPi / 180.0},
                                                 {"rpm", 2.0 * kPi / 60.0},
                                                 {"rev/s", 2.0 * kPi},
                                                 {"deg/min", kPi / 180.0 / 60.0}});
  u.rotary_acceleration = rotary(
      "rotary_acceleration", {{"rad/s^2", 1.0}, {"deg/s^2", kPi / 180.0}, {"rev/s^2", 2.0 * kPi}});
  u.rotary_jerk =
      rotary("rotary_jerk", {{"rad/s^3", 1.0}, {"deg/s^3", kPi / 180.0}, {"rev/s^3", 2.0 * kPi}});
  t.RejectUnknown();
  return u;
}

Axis ReadAxis(TomlTable& axes, const std::string& name, bool rotary, const Units& u) {
  if (!axes.Has(name)) {
    axes.Fail(name, fmt::format("missing axis table [axes.{}]; this kinematics needs it", name));
  }
  TomlTable t = axes.Table(name);
  Axis a;
  a.name = name;
  a.rotary = rotary;
  const double k = rotary ? u.angle : u.length;
  if (rotary && t.IsString("travel")) {
    // Only "continuous" is allowed as a string.
    t.Choice("travel", {"continuous"});
    a.continuous = true;
    a.travel_min = -INFINITY;
    a.travel_max = INFINITY;
  } else {
    const auto travel = t.Numbers("travel");
    if (travel.size() != 2 || !(travel[0] < travel[1])) {
      t.Fail("travel", rotary ? "expected [min, max] with min < max, or \"continuous\""
                              : "expected [min, max] with min < max");
    }
    a.travel_min = travel[0] * k;
    a.travel_max = travel[1] * k;
  }
  a.vmax = t.PositiveNumber("velocity") * (rotary ? u.rotary_velocity : u.linear_velocity);
  a.amax =
      t.PositiveNumber("acceleration") * (rotary ? u.rotary_acceleration : u.linear_acceleration);
  a.jmax = t.PositiveNumber("jerk") * (rotary ? u.rotary_jerk : u.linear_jerk);
  t.RejectUnknown();
  return a;
}

// The machine file's key for the point on the tilting axis: "a_axis" or "b_axis".
std::string TiltPivotKey(Kinematics k) {
  return fmt::format("{}_axis", static_cast<char>(std::tolower(AxisLetters(k)[3])));
}

// Six numbers, one per joint J1..J6, times `scale`; all 0 when the key is optional and absent.
std::array<double, 6> SixNumbers(TomlTable& t, std::string_view key, double scale, bool required) {
  std::array<double, 6> out{};
  if (!required && !t.Has(key)) return out;
  const auto v = t.Numbers(key);
  if (v.size() != 6) t.Fail(key, "expected 6 numbers, one per joint J1..J6");
  for (std::size_t i = 0; i < 6; ++i) out[i] = v[i] * scale;
  return out;
}

std::array<Eigen::Vector3d, 6> SixPoints(TomlTable& t, std::string_view key, double scale,
                                         bool required) {
  std::array<Eigen::Vector3d, 6> out;
  out.fill(Eigen::Vector3d::Zero());
  if (!required && !t.Has(key)) return out;
  const auto v = t.Points(key);
  if (v.size() != 6) t.Fail(key, "expected 6 points [x, y, z], one per joint J1..J6");
  for (std::size_t i = 0; i < 6; ++i) out[i] = v[i] * scale;
  return out;
}

Eigen::Vector3d Direction(TomlTable& t, std::string_view key) {
  const Eigen::Vector3d v = t.Point(key);
  if (!(v.norm() > 0.0)) t.Fail(key, "expected a direction [x, y, z], not zero");
  return v.normalized();
}

// A six-joint serial arm: joints J1..J6, the chain as [frames] or [dh], the tool, the part's
// placement and which joint is locked (docs/robots.md).
void ReadArm(TomlTable& root, MachineDescription* d) {
  TomlTable units_table = root.Table("units");
  const Units u = ReadUnits(units_table, true, false);
  TomlTable axes_table = root.Table("axes");
  std::vector<std::string> joints;
  for (int i = 1; i <= 6; ++i) joints.push_back(fmt::format("J{}", i));
  for (const std::string& n : joints) d->axes.push_back(ReadAxis(axes_table, n, true, u));
  axes_table.RejectUnknown();
  ArmDescription& arm = d->arm;
  const bool frames = root.Has("frames"), dh = root.Has("dh");
  if (frames == dh) {
    root.Fail(frames ? "dh" : "frames",
              "expected the arm's chain once: a [frames] table (joint origins, rotations and "
              "axes) or a [dh] table (modified Denavit-Hartenberg parameters)");
  }
  if (frames) {
    TomlTable f = root.Table("frames");
    arm.form = ArmDescription::Form::kFrames;
    arm.origin = SixPoints(f, "origin", u.length, true);
    arm.rpy = SixPoints(f, "rpy", u.angle, false);
    arm.axis = SixPoints(f, "axis", 1.0, true);
    for (const Eigen::Vector3d& a : arm.axis) {
      if (!(a.norm() > 0.0)) f.Fail("axis", "expected 6 directions, none of them zero");
    }
    f.RejectUnknown();
  } else {
    TomlTable t = root.Table("dh");
    arm.form = ArmDescription::Form::kDh;
    t.Choice("convention", {"modified"});
    arm.a = SixNumbers(t, "a", u.length, true);
    arm.alpha = SixNumbers(t, "alpha", u.angle, true);
    arm.d = SixNumbers(t, "d", u.length, true);
    arm.theta = SixNumbers(t, "theta", u.angle, false);
    t.RejectUnknown();
  }
  TomlTable tool = root.Table("tool");
  arm.tool_tip = tool.Point("tip") * u.length;
  arm.tool_axis = Direction(tool, "axis");
  tool.RejectUnknown();
  TomlTable part = root.Table("part");
  arm.part_origin = part.Point("origin") * u.length;
  arm.part_rpy = part.OptionalPoint("rpy").value_or(Eigen::Vector3d::Zero()) * u.angle;
  part.RejectUnknown();
  TomlTable a = root.Table("arm");
  arm.home = SixNumbers(a, "home", u.angle, true);
  const std::string locked = a.Choice("locked_joint", joints);
  arm.locked_joint = locked[1] - '1';
  arm.locked_at = a.OptionalNumber("locked_at")
                      .value_or(arm.home[static_cast<std::size_t>(arm.locked_joint)] / u.angle) *
                  u.angle;
  if (arm.locked_joint != 5 && ToolOnLastAxis(arm)) {
    a.Fail("locked_joint",
           "the tool lies on J6's axis, so J6 only turns it about its own axis: expected \"J6\"");
  }
  // The arm starts every path from home with the locked joint where it stays: both within travel.
  const auto within = [&](std::string_view key, std::size_t joint, double value) {
    const Axis& j = d->axes[joint];
    if (!j.continuous && (value < j.travel_min || value > j.travel_max)) {
      a.Fail(key,
             fmt::format("{} at {:g} is outside its travel [{:g}, {:g}] (in the file's angle "
                         "unit)",
                         j.name, value / u.angle, j.travel_min / u.angle, j.travel_max / u.angle));
    }
  };
  for (std::size_t i = 0; i < 6; ++i) within("home", i, arm.home[i]);
  within(a.Has("locked_at") ? "locked_at" : "locked_joint",
         static_cast<std::size_t>(arm.locked_joint), arm.locked_at);
  if (const auto margin = a.OptionalNumber("singularity_margin")) {
    if (!(*margin > 0.0 && *margin * u.angle < kPi / 4)) {
      a.Fail("singularity_margin", "expected an angle > 0 and below 45 deg");
    }
    arm.singular_sine = std::sin(*margin * u.angle);
  }
  a.RejectUnknown();
  root.RejectUnknown();
}

MachineDescription ReadMachine(TomlTable& root) {
  MachineDescription d;
  d.name = root.String("name");
  d.kinematics = *KinematicsNamed(root.Choice("kinematics", KinematicsNames()));
  if (d.kinematics == Kinematics::kSerialArm) {
    ReadArm(root, &d);
    return d;
  }
  const bool five_axis = d.kinematics != Kinematics::kXyz;
  TomlTable units_table = root.Table("units");
  const Units units = ReadUnits(units_table, five_axis);
  TomlTable axes_table = root.Table("axes");
  for (const char* n : {"X", "Y", "Z"}) d.axes.push_back(ReadAxis(axes_table, n, false, units));
  if (!five_axis) {
    axes_table.RejectUnknown();
    root.RejectUnknown();
    return d;
  }
  const std::string tilt(1, AxisLetters(d.kinematics)[3]);
  for (const std::string& n : {tilt, std::string("C")}) {
    d.axes.push_back(ReadAxis(axes_table, n, true, units));
  }
  axes_table.RejectUnknown();
  TomlTable pivot = root.Table("pivot");
  d.c_pivot = pivot.Point("c_axis") * units.length;
  if (IsHeadTable(d.kinematics)) {
    const double length = pivot.Number("head_length");
    if (!(length >= 0.0)) pivot.Fail("head_length", "expected a length >= 0");
    d.head_length_mm = length * units.length;
    if (auto directions = root.OptionalTable("directions")) {
      const auto direction = [&](const std::string& axis) {
        const auto v = directions->OptionalNumber(axis);
        if (v && *v != 1.0 && *v != -1.0) directions->Fail(axis, "expected 1 or -1");
        return v.value_or(1.0);
      };
      d.head_direction = direction(tilt);
      d.c_direction = direction("C");
      directions->RejectUnknown();
    }
  } else {
    d.tilt_pivot = pivot.Point(TiltPivotKey(d.kinematics)) * units.length;
  }
  pivot.RejectUnknown();
  root.RejectUnknown();
  return d;
}

std::string Number(double v) { return fmt::format("{:.15g}", v + 0.0); }  // no "-0"

std::string Point(const Eigen::Vector3d& p) {
  return fmt::format("[{}, {}, {}]", Number(p.x()), Number(p.y()), Number(p.z()));
}

std::string Numbers(const std::array<double, 6>& v, double scale) {
  return fmt::format("[{}, {}, {}, {}, {}, {}]", Number(v[0] * scale), Number(v[1] * scale),
                     Number(v[2] * scale), Number(v[3] * scale), Number(v[4] * scale),
                     Number(v[5] * scale));
}

std::string Points(const std::array<Eigen::Vector3d, 6>& v, double scale) {
  std::string out = "[";
  for (std::size_t i = 0; i < 6; ++i) out += (i ? ", " : "") + Point(v[i] * scale);
  return out + "]";
}

// An arm's chain, tool, part and locked joint, in mm and deg.
std::string FormatArm(const ArmDescription& arm) {
  constexpr double kDeg = 180.0 / kPi;
  std::string out;
  if (arm.form == ArmDescription::Form::kFrames) {
    out += fmt::format("\n[frames]\norigin = {}\nrpy = {}\naxis = {}\n", Points(arm.origin, 1.0),
                       Points(arm.rpy, kDeg), Points(arm.axis, 1.0));
  } else {
    out +=
        fmt::format("\n[dh]\nconvention = \"modified\"\na = {}\nalpha = {}\nd = {}\ntheta = {}\n",
                    Numbers(arm.a, 1.0), Numbers(arm.alpha, kDeg), Numbers(arm.d, 1.0),
                    Numbers(arm.theta, kDeg));
  }
  out += fmt::format("\n[tool]\ntip = {}\naxis = {}\n", Point(arm.tool_tip), Point(arm.tool_axis));
  out += fmt::format("\n[part]\norigin = {}\nrpy = {}\n", Point(arm.part_origin),
                     Point(arm.part_rpy * kDeg));
  out += fmt::format(
      "\n[arm]\nhome = {}\nlocked_joint = \"J{}\"\nlocked_at = {}\nsingularity_margin = {}\n",
      Numbers(arm.home, kDeg), arm.locked_joint + 1, Number(arm.locked_at * kDeg),
      Number(std::asin(arm.singular_sine) * kDeg));
  return out;
}

}  // namespace

bool IsLinuxcncIni(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  return ext == ".ini" || ext == ".INI";
}

MachineDescription ParseMachineDescription(std::string_view text, const std::string& source_name) {
  TomlTable root = TomlTable::ParseString(text, source_name);
  return ReadMachine(root);
}

std::unique_ptr<Machine> ParseMachine(std::string_view text, const std::string& source_name) {
  return BuildMachine(ParseMachineDescription(text, source_name));
}

MachineDescription ReadMachineDescription(const std::string& path,
                                          const MachineLoadOptions& options) {
  if (const auto t = options.jerk_time_s;
      t && !(*t >= MachineLoadOptions::kMinJerkTimeS && *t <= MachineLoadOptions::kMaxJerkTimeS)) {
    throw Error(
        "{}: jerk time (machine_jerk_time_ms or --jerk-time-ms) {:g} ms: expected a time from "
        "{:g} to {:g} ms (each axis' jerk is its acceleration over it)",
        path, *t * 1e3, MachineLoadOptions::kMinJerkTimeS * 1e3,
        MachineLoadOptions::kMaxJerkTimeS * 1e3);
  }
  if (IsLinuxcncIni(path)) {
    const auto text = ReadFileText(path);
    if (!text) throw Error("{}: cannot open the LinuxCNC INI file", path);
    return ParseLinuxcncIni(*text, path, options);
  }
  TomlTable root = TomlTable::ParseFile(path);
  return ReadMachine(root);
}

std::unique_ptr<Machine> LoadMachineFile(const std::string& path,
                                         const MachineLoadOptions& options) {
  return BuildMachine(ReadMachineDescription(path, options));
}

std::string FormatMachineFile(const MachineDescription& d) {
  constexpr double kDeg = 180.0 / kPi;
  std::string out =
      fmt::format("name = \"{}\"\nkinematics = \"{}\"\n\n", d.name, KinematicsName(d.kinematics));
  out +=
      "[units]\nlength = \"mm\"\nangle = \"deg\"\nlinear_velocity = \"mm/s\"\n"
      "linear_acceleration = \"mm/s^2\"\nlinear_jerk = \"mm/s^3\"\n"
      "rotary_velocity = \"deg/s\"\nrotary_acceleration = \"deg/s^2\"\n"
      "rotary_jerk = \"deg/s^3\"\n";
  for (const Axis& a : d.axes) {
    const double k = a.rotary ? kDeg : 1.0;
    out += fmt::format("\n[axes.{}]\n", a.name);
    out += a.continuous ? std::string("travel = \"continuous\"\n")
                        : fmt::format("travel = [{}, {}]\n", Number(a.travel_min * k),
                                      Number(a.travel_max * k));
    out += fmt::format("velocity = {}\nacceleration = {}\njerk = {}\n", Number(a.vmax * k),
                       Number(a.amax * k), Number(a.jmax * k));
  }
  if (d.kinematics == Kinematics::kXyz) return out;
  if (d.kinematics == Kinematics::kSerialArm) return out + FormatArm(d.arm);
  out += fmt::format("\n[pivot]\nc_axis = {}\n", Point(d.c_pivot));
  if (IsHeadTable(d.kinematics)) {
    out += fmt::format("head_length = {}\n", Number(d.head_length_mm));
    out += fmt::format("\n[directions]\n{} = {}\nC = {}\n", AxisLetters(d.kinematics)[3],
                       Number(d.head_direction), Number(d.c_direction));
  } else {
    out += fmt::format("{} = {}\n", TiltPivotKey(d.kinematics), Point(d.tilt_pivot));
  }
  return out;
}

}  // namespace dtis::kinematics
