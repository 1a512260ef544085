// Machine files: TOML with the units stated in the file, converted to mm, s, rad on reading.
#include <cmath>
#include <map>
#include <numbers>

#include "dtis/core/error.hpp"
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
// may state them (they are checked) or leave them out.
Units ReadUnits(TomlTable& t, bool rotary_axes) {
  Units u;
  u.length = Unit(t, "length", {{"mm", 1.0}, {"m", 1000.0}, {"in", 25.4}});
  // A unit only rotary axes use: read when they exist or the file states it, else left at 1.
  const auto rotary = [&](std::string_view key, const std::map<std::string, double>& factors) {
    return rotary_axes || t.Has(key) ? Unit(t, key, factors) : 1.0;
  };
  u.angle = rotary("angle", {{"deg", kPi / 180.0}, {"rad", 1.0}});
  u.linear_velocity = Unit(t, "linear_velocity",
                           {{"mm/s", 1.0},
                            {"mm/min", 1.0 / 60.0},
                            {"m/s", 1000.0},
                            {"m/min", 1000.0 / 60.0},
                            {"in/min", 25.4 / 60.0}});
  u.linear_acceleration = Unit(t, "linear_acceleration", {{"mm/s^2", 1.0}, {"m/s^2", 1000.0}});
  u.linear_jerk = Unit(t, "linear_jerk", {{"mm/s^3", 1.0}, {"m/s^3", 1000.0}});
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

std::unique_ptr<Machine> ReadMachine(TomlTable& root) {
  const std::string name = root.String("name");
  const std::string kinematics = root.Choice("kinematics", {"xyz", "xyzac"});
  TomlTable units_table = root.Table("units");
  const Units units = ReadUnits(units_table, kinematics != "xyz");
  TomlTable axes_table = root.Table("axes");
  std::vector<Axis> axes;
  for (const char* n : {"X", "Y", "Z"}) axes.push_back(ReadAxis(axes_table, n, false, units));
  KinematicsOptions options;
  if (kinematics == "xyz") {
    axes_table.RejectUnknown();
    root.RejectUnknown();
    return std::make_unique<XyzMachine>(name, std::move(axes), options);
  }
  for (const char* n : {"A", "C"}) axes.push_back(ReadAxis(axes_table, n, true, units));
  axes_table.RejectUnknown();
  TomlTable pivot = root.Table("pivot");
  const Eigen::Vector3d a_pivot = pivot.Point("a_axis") * units.length;
  const Eigen::Vector3d c_pivot = pivot.Point("c_axis") * units.length;
  pivot.RejectUnknown();
  root.RejectUnknown();
  return std::make_unique<XyzacMachine>(name, std::move(axes), a_pivot, c_pivot, options);
}

}  // namespace

std::unique_ptr<Machine> ParseMachine(std::string_view text, const std::string& source_name) {
  TomlTable root = TomlTable::ParseString(text, source_name);
  return ReadMachine(root);
}

std::unique_ptr<Machine> LoadMachineFile(const std::string& path) {
  TomlTable root = TomlTable::ParseFile(path);
  return ReadMachine(root);
}

}  // namespace dtis::kinematics
