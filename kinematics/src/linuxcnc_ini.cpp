// LinuxCNC INI files read as dtis machines: the kinematics module named in [KINS] KINEMATICS, the
// axis letters of [TRAJ] COORDINATES mapped to joints as the module maps them, the limits of
// [JOINT_n] and [AXIS_L] in the file's LINEAR_UNITS and ANGULAR_UNITS, and the module's pivot pins
// as the INI's HAL files and HALCMD lines set them.
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::kinematics {
namespace {

constexpr double kPi = std::numbers::pi;

std::string Trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  const auto e = s.find_last_not_of(" \t\r");
  return std::string(s.substr(b, e - b + 1));
}

std::string Upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::optional<double> ParseNumber(std::string_view s) { return ParseFiniteNumber(Trim(s)); }

// The INI as LinuxCNC reads it: [SECTION], KEY = VALUE (repeatable), comments on lines starting
// with # or ;, a trailing backslash continuing a line, #INCLUDE FILE (relative to the including
// file's directory) read in its place.
class IniFile {
 public:
  struct Entry {
    std::string section, key, value, file;
    int line = 0;
  };

  IniFile(std::string_view text, const std::string& name) { Read(text, name, 0); }

  const Entry* Find(const std::string& section, const std::string& key) const {
    for (const Entry& e : entries_) {
      if (e.section == section && e.key == key) return &e;
    }
    return nullptr;
  }
  std::vector<const Entry*> All(const std::string& section, const std::string& key) const {
    std::vector<const Entry*> out;
    for (const Entry& e : entries_) {
      if (e.section == section && e.key == key) out.push_back(&e);
    }
    return out;
  }
  bool HasSection(const std::string& section) const {
    for (const Entry& e : entries_) {
      if (e.section == section) return true;
    }
    return false;
  }

 private:
  void Read(std::string_view text, const std::string& name, int depth) {
    if (depth > 8) throw Error("{}: #INCLUDE nested more than 8 deep", name);
    std::istringstream in{std::string(text)};
    std::string raw;
    int number = 0;
    while (std::getline(in, raw)) {
      ++number;
      const int first = number;
      std::string line = Trim(raw);
      while (!line.empty() && line.back() == '\\' && std::getline(in, raw)) {
        ++number;
        line.pop_back();
        line += Trim(raw);
      }
      if (line.rfind("#INCLUDE", 0) == 0) {
        std::filesystem::path p = Trim(std::string_view(line).substr(8));
        if (p.is_relative()) p = std::filesystem::path(name).parent_path() / p;
        const auto included = ReadFileText(p.string());
        if (!included)
          throw Error("{}:{}: cannot read the #INCLUDE file {}", name, first, p.string());
        Read(*included, p.string(), depth + 1);
        continue;
      }
      if (line.empty() || line[0] == '#' || line[0] == ';') continue;
      if (line[0] == '[') {
        const auto close = line.find(']');
        if (close == std::string::npos) throw Error("{}:{}: expected [SECTION]", name, first);
        section_ = Trim(std::string_view(line).substr(1, close - 1));
        // LinuxCNC reads a key from the first of two sections of one name: a second [AXIS_X]
        // would be ignored, its limits unseen. The sections dtis reads appear once.
        const bool read = section_ == "KINS" || section_ == "TRAJ" ||
                          section_.rfind("JOINT_", 0) == 0 || section_.rfind("AXIS_", 0) == 0;
        for (const auto& [seen, where] : sections_) {
          if (read && seen == section_) {
            throw Error(
                "{}:{}: [{}] appears a second time (first at {}); LinuxCNC reads only the "
                "first: expected each section once",
                name, first, section_, where);
          }
        }
        sections_.emplace_back(section_, fmt::format("{}:{}", name, first));
        continue;
      }
      const auto eq = line.find('=');
      if (eq == std::string::npos) continue;  // LinuxCNC ignores lines without '='
      entries_.push_back({section_, Trim(std::string_view(line).substr(0, eq)),
                          Trim(std::string_view(line).substr(eq + 1)), name, first});
    }
  }

  std::vector<Entry> entries_;
  std::string section_;
  std::vector<std::pair<std::string, std::string>> sections_;  // name, where it began
};

// The pins HAL commands leave set: setp PIN VALUE, PIN = VALUE, sets SIGNAL VALUE with the
// signal netted to the pin; [SECTION]KEY words take their INI values.
class HalPins {
 public:
  explicit HalPins(const IniFile& ini) : ini_(ini) {}

  void Command(const std::string& text) {
    std::vector<std::string> words;
    std::istringstream in(text.substr(0, text.find('#')));
    for (std::string w; in >> w;) words.push_back(Substitute(w));
    if (words.empty()) return;
    if (words[0] == "setp" && words.size() >= 3) {
      pins_[words[1]] = words[2];
    } else if (words.size() == 3 && words[1] == "=") {
      pins_[words[0]] = words[2];
    } else if (words[0] == "sets" && words.size() >= 3) {
      signals_[words[1]] = words[2];
    } else if (words[0] == "net" && words.size() >= 3) {
      for (std::size_t i = 2; i < words.size(); ++i) {
        if (words[i] != "=>" && words[i] != "<=" && words[i] != "<=>") nets_[words[i]] = words[1];
      }
    }
  }

  // False when the file cannot be read.
  bool File(const std::string& path) {
    const auto text = ReadFileText(path);
    if (!text) return false;
    std::istringstream in(*text);
    for (std::string line; std::getline(in, line);) Command(line);
    return true;
  }

  std::optional<std::string> Value(const std::string& pin) const {
    if (const auto n = nets_.find(pin); n != nets_.end()) {
      if (const auto s = signals_.find(n->second); s != signals_.end()) return s->second;
    }
    if (const auto p = pins_.find(pin); p != pins_.end()) return p->second;
    return std::nullopt;
  }

 private:
  std::string Substitute(const std::string& word) const {
    if (word.size() < 3 || word[0] != '[') return word;
    const auto close = word.find(']');
    if (close == std::string::npos) return word;
    std::string key = word.substr(close + 1);
    if (key.size() > 2 && key.front() == '(' && key.back() == ')')
      key = key.substr(1, key.size() - 2);
    const auto* e = ini_.Find(word.substr(1, close - 1), key);
    return e ? e->value : word;
  }

  const IniFile& ini_;
  std::map<std::string, std::string> pins_, signals_, nets_;
};

struct Module {
  const char* name;
  Kinematics kinematics;
  const char* default_coordinates;
  bool fixed_joints;  // joints 0..8 are X..W whatever the coordinates (maxkins)
};
constexpr Module kModules[] = {
    {"trivkins", Kinematics::kXyz, "XYZABCUVW", false},
    {"xyzac-trt-kins", Kinematics::kXyzacTrt, "XYZAC", false},
    {"xyzbc-trt-kins", Kinematics::kXyzbcTrt, "XYZBC", false},
    {"maxkins", Kinematics::kXyzbcHeadTable, "XYZABCUVW", true},
    {"genserkins", Kinematics::kSerialArm, "XYZABC", false},
    {"pumakins", Kinematics::kSerialArm, "XYZABC", false},
};

class IniMachineReader {
 public:
  IniMachineReader(std::string_view text, const std::string& name, const MachineLoadOptions& o)
      : ini_(text, name), name_(name), options_(o) {}

  MachineDescription Read() {
    MachineDescription d;
    const auto* machine = ini_.Find("EMC", "MACHINE");
    d.name = machine ? machine->value : std::filesystem::path(name_).stem().string();
    const IniFile::Entry& kins = Require("KINS", "KINEMATICS");
    std::istringstream words(kins.value);
    std::string module_name;
    words >> module_name;
    std::string coordinates;
    for (std::string w; words >> w;) {
      if (w.rfind("coordinates=", 0) == 0) coordinates = Upper(w.substr(12));
    }
    const Module* module = nullptr;
    for (const Module& m : kModules) {
      if (module_name == m.name) module = &m;
    }
    if (!module) {
      Fail(kins, fmt::format("kinematics '{}' is not one dtis models (trivkins, xyzac-trt-kins, "
                             "xyzbc-trt-kins, maxkins, genserkins, pumakins)",
                             module_name));
    }
    d.kinematics = module->kinematics;
    if (d.kinematics == Kinematics::kSerialArm) {
      ReadUnits();
      ReadArm(module_name, &d);
      return d;
    }
    const std::string traj = Coordinates();
    if (coordinates.empty()) coordinates = traj.empty() ? module->default_coordinates : traj;
    ReadUnits();

    const std::string letters = AxisLetters(d.kinematics);
    // The axes the machine moves must be ones dtis models (the module may define more).
    const std::string& used = traj;
    for (char c : used) {
      if (letters.find(c) == std::string::npos) {
        const auto* at = ini_.Find("TRAJ", "COORDINATES");
        Fail(at ? *at : kins,
             fmt::format("axis {} of coordinates {}: a {} machine in dtis has the axes {} (rotary "
                         "axes without kinematics cannot orient the tool)",
                         c, used, module_name, letters));
      }
    }
    for (char c : letters) {
      const auto position =
          module->fixed_joints ? std::string("XYZABCUVW").find(c) : coordinates.find(c);
      if (position == std::string::npos) {
        Fail(kins, fmt::format("{} needs axis {} in its coordinates, got {}", module_name, c,
                               coordinates));
      }
      d.axes.push_back(ReadAxis(c, static_cast<int>(position), module == &kModules[0]));
    }
    if (const auto* joints = ini_.Find("KINS", "JOINTS")) {
      // LinuxCNC's motion controller has at most 16 joints (EMCMOT_MAX_JOINTS).
      const auto n = ParseNumber(joints->value);
      if (!n || *n != std::floor(*n) || *n < 1 || *n > 16) {
        Fail(*joints, fmt::format("expected a whole number of joints from 1 to 16 (LinuxCNC's "
                                  "most), got '{}'",
                                  joints->value));
      }
    }
    if (d.kinematics != Kinematics::kXyz) ReadPivots(module_name, &d);
    return d;
  }

 private:
  [[noreturn]] void Fail(const IniFile::Entry& e, const std::string& what) const {
    throw Error("{}:{}: [{}] {}: {}", e.file, e.line, e.section, e.key, what);
  }

  const IniFile::Entry& Require(const std::string& section, const std::string& key) const {
    const auto* e = ini_.Find(section, key);
    if (!e) throw Error("{}: [{}] {} is missing", name_, section, key);
    return *e;
  }

  std::string Coordinates() const {
    const auto* e = ini_.Find("TRAJ", "COORDINATES");
    std::string out;
    if (e) {
      for (char c : Upper(e->value)) {
        if (c != ' ' && c != '\t') out += c;
      }
    }
    return out;
  }

  // mm/metric/inch/imperial, or a number of machine units per mm (per degree for angles), as
  // LinuxCNC reads them.
  void ReadUnits() {
    if (const auto* e = ini_.Find("TRAJ", "LINEAR_UNITS")) {
      const std::string v = Upper(e->value);
      if (v == "MM" || v == "METRIC") {
        length_ = 1.0;
      } else if (v == "IN" || v == "INCH" || v == "IMPERIAL") {
        length_ = 25.4;
      } else if (const auto n = ParseNumber(v); n && *n > 0.0) {
        length_ = 1.0 / *n;
      } else {
        Fail(*e, fmt::format("expected mm, inch or a number of units per mm, got '{}'", e->value));
      }
    }
    if (const auto* e = ini_.Find("TRAJ", "ANGULAR_UNITS")) {
      const std::string v = Upper(e->value);
      if (v == "DEG" || v == "DEGREE") {
        angle_ = kPi / 180.0;
      } else if (v == "RAD" || v == "RADIAN") {
        angle_ = 1.0;
      } else if (v == "GRAD" || v == "GON") {
        angle_ = kPi / 200.0;
      } else if (const auto n = ParseNumber(v); n && *n > 0.0) {
        angle_ = kPi / 180.0 / *n;
      } else {
        Fail(*e, fmt::format("expected deg, rad, grad or a number of units per degree, got '{}'",
                             e->value));
      }
    }
  }

  // The key's value in [JOINT_n] and [AXIS_L], each checked to be a number, with its line.
  struct Given {
    double value;
    const IniFile::Entry* entry;
  };
  struct Pair {
    std::optional<Given> joint, axis;
  };
  Pair Values(int joint, char letter, const std::string& key) const {
    const auto read = [&](const std::string& section) -> std::optional<Given> {
      const auto* e = ini_.Find(section, key);
      if (!e) return std::nullopt;
      const auto v = ParseNumber(e->value);
      if (!v) Fail(*e, fmt::format("expected a number, got '{}'", e->value));
      return Given{*v, e};
    };
    return {read(fmt::format("JOINT_{}", joint)), read(fmt::format("AXIS_{}", letter))};
  }

  [[noreturn]] void Missing(int joint, char letter, const std::string& key,
                            std::string_view remedy = "") const {
    throw Error("{}: neither [JOINT_{}] nor [AXIS_{}] gives {}{}", name_, joint, letter, key,
                remedy);
  }

  // The tighter of the joint's and the axis' limit: the machine enforces both. NaN when neither
  // gives it and it is not required.
  double Limit(int joint, char letter, const std::string& key, bool required) const {
    const Pair p = Values(joint, letter, key);
    if (!p.joint && !p.axis) {
      if (!required) return NAN;
      Missing(joint, letter, key);
    }
    for (const auto& given : {p.joint, p.axis}) {
      if (given && !(given->value > 0.0)) {
        Fail(*given->entry, fmt::format("expected a number > 0, got {}", given->entry->value));
      }
    }
    return std::min(p.joint ? p.joint->value : INFINITY, p.axis ? p.axis->value : INFINITY);
  }

  Axis ReadAxis(char letter, int joint, bool identity) const {
    Axis a;
    a.name = std::string(1, letter);
    a.rotary = letter >= 'A' && letter <= 'C';
    const double k = a.rotary ? angle_ : length_;
    a.vmax = Limit(joint, letter, "MAX_VELOCITY", true) * k;
    a.amax = Limit(joint, letter, "MAX_ACCELERATION", true) * k;
    const double jerk = Limit(joint, letter, "MAX_JERK", false);
    if (!std::isnan(jerk)) {
      a.jmax = jerk * k;
    } else if (options_.jerk_time_s) {
      a.jmax = a.amax / *options_.jerk_time_s;
    } else {
      Missing(joint, letter, "MAX_JERK",
              "; give the job key machine_jerk_time_ms (or --jerk-time-ms): jerk = "
              "MAX_ACCELERATION / jerk time");
    }
    // Travel: the joint's (machine frame); with identity kinematics the axis' too.
    const Pair lo = Values(joint, letter, "MIN_LIMIT");
    const Pair hi = Values(joint, letter, "MAX_LIMIT");
    const auto* wrapped = ini_.Find(fmt::format("AXIS_{}", letter), "WRAPPED_ROTARY");
    const bool has_limits = lo.joint || lo.axis || hi.joint || hi.axis;
    if (a.rotary && (!has_limits || (wrapped && wrapped->value != "0"))) {
      a.continuous = true;
      a.travel_min = -INFINITY;
      a.travel_max = INFINITY;
      return a;
    }
    // LinuxCNC takes +-1e99 for a limit not given; a linear axis has to state its travel here.
    if (!lo.joint && !lo.axis) Missing(joint, letter, "MIN_LIMIT");
    if (!hi.joint && !hi.axis) Missing(joint, letter, "MAX_LIMIT");
    double min = (lo.joint ? *lo.joint : *lo.axis).value;
    double max = (hi.joint ? *hi.joint : *hi.axis).value;
    if (identity) {
      if (lo.axis) min = std::max(min, lo.axis->value);
      if (hi.axis) max = std::min(max, hi.axis->value);
    }
    if (!(min < max)) {
      throw Error("{}: axis {} (joint {}) has MIN_LIMIT {} not below MAX_LIMIT {}", name_, letter,
                  joint, min, max);
    }
    a.travel_min = min * k;
    a.travel_max = max * k;
    return a;
  }

  // The pins the INI's HAL files and HALCMD lines leave set.
  HalPins Pins(const std::string& module) const {
    HalPins pins(ini_);
    const std::filesystem::path dir = std::filesystem::path(name_).parent_path();
    // A HAL file that cannot be read may hold the pivots: an error, never a pivot silently at 0
    // (LinuxCNC would not start either). Tcl HAL files are not read.
    const auto hal_file = [&](const IniFile::Entry& e) {
      std::filesystem::path p = e.value;
      if (e.value.rfind("LIB:", 0) == 0) {
        p = std::filesystem::path("/usr/share/linuxcnc/hallib") / e.value.substr(4);
      } else if (p.is_relative()) {
        p = dir / p;
      }
      if (p.extension() != ".tcl" && !pins.File(p.string())) {
        Fail(e, fmt::format("cannot read {}, where {}'s pivots may be set", p.string(), module));
      }
    };
    for (const auto* e : ini_.All("HAL", "HALFILE")) hal_file(*e);
    for (const auto* e : ini_.All("HAL", "HALCMD")) pins.Command(e->value);
    for (const auto* e : ini_.All("HAL", "POSTGUI_HALFILE")) hal_file(*e);
    return pins;
  }

  // A number pin of the module, or `fallback` when nothing sets it.
  double Pin(const HalPins& pins, const std::string& module, const std::string& name,
             double fallback) const {
    const auto v = pins.Value(module + "." + name);
    if (!v) return fallback;
    const auto n = ParseNumber(*v);
    if (!n) throw Error("{}: HAL sets {}.{} to '{}', expected a number", name_, module, name, *v);
    return *n;
  }

  // A six-joint arm: [JOINT_0..5] limits in degrees (both modules take their joints in degrees),
  // the chain from the module's pins in the INI's length unit, the last frame as the tool's (its
  // +z out of the flange, the tool length in D-5 or D6), the part frame the arm's world frame,
  // home at the joints' HOME, J6 locked there.
  void ReadArm(const std::string& module, MachineDescription* d) const {
    if (const auto* joints = ini_.Find("KINS", "JOINTS")) {
      const auto n = ParseNumber(joints->value);
      if (!n || *n != 6) {
        Fail(*joints, fmt::format("{} in dtis drives six joints (an arm's), got '{}'; the extra "
                                  "joints LinuxCNC passes through are not modelled",
                                  module, joints->value));
      }
    }
    if (const auto* e = ini_.Find("TRAJ", "ANGULAR_UNITS"); e && angle_ != kPi / 180.0) {
      Fail(*e, fmt::format("{} takes its joints in degrees: expected deg", module));
    }
    const double deg = kPi / 180.0;
    for (int j = 0; j < 6; ++j) {
      const std::string section = fmt::format("JOINT_{}", j);
      const auto value = [&](const std::string& key, bool required) -> std::optional<double> {
        const auto* e = ini_.Find(section, key);
        if (!e) {
          if (required) throw Error("{}: [{}] {} is missing", name_, section, key);
          return std::nullopt;
        }
        const auto v = ParseNumber(e->value);
        if (!v) Fail(*e, fmt::format("expected a number, got '{}'", e->value));
        return *v;
      };
      const auto positive = [&](const std::string& key, bool required) -> std::optional<double> {
        const auto v = value(key, required);
        if (v && !(*v > 0.0)) Fail(*ini_.Find(section, key), "expected a number > 0");
        return v;
      };
      Axis a;
      a.name = fmt::format("J{}", j + 1);
      a.rotary = true;
      a.vmax = *positive("MAX_VELOCITY", true) * deg;
      a.amax = *positive("MAX_ACCELERATION", true) * deg;
      if (const auto jerk = positive("MAX_JERK", false)) {
        a.jmax = *jerk * deg;
      } else if (options_.jerk_time_s) {
        a.jmax = a.amax / *options_.jerk_time_s;
      } else {
        throw Error(
            "{}: [{}] gives no MAX_JERK; give the job key machine_jerk_time_ms (or "
            "--jerk-time-ms): jerk = MAX_ACCELERATION / jerk time",
            name_, section);
      }
      const auto lo = value("MIN_LIMIT", false), hi = value("MAX_LIMIT", false);
      if (!lo || !hi) {
        a.continuous = true;
        a.travel_min = -INFINITY;
        a.travel_max = INFINITY;
      } else if (!(*lo < *hi)) {
        throw Error("{}: [{}] MIN_LIMIT {} not below MAX_LIMIT {}", name_, section, *lo, *hi);
      } else {
        a.travel_min = *lo * deg;
        a.travel_max = *hi * deg;
      }
      d->arm.home[static_cast<std::size_t>(j)] = value("HOME", false).value_or(0.0) * deg;
      d->axes.push_back(a);
    }
    ArmDescription& arm = d->arm;
    arm.form = ArmDescription::Form::kDh;
    arm.tool_tip = Eigen::Vector3d::Zero();
    arm.tool_axis = -Eigen::Vector3d::UnitZ();
    arm.locked_joint = 5;
    arm.locked_at = arm.home[5];
    const HalPins pins = Pins(module);
    if (module == "pumakins") {
      // Craig's PUMA 560: the modified DH chain pumakins' closed forms are written for.
      const double h = kPi / 2;
      arm.a = {0, 0, Pin(pins, module, "A2", 300.0), Pin(pins, module, "A3", 50.0), 0, 0};
      arm.alpha = {0, -h, 0, -h, h, -h};
      arm.d = {0,
               0,
               Pin(pins, module, "D3", 70.0),
               Pin(pins, module, "D4", 400.0),
               0,
               Pin(pins, module, "D6", 70.0)};
    } else {
      // genserkins' defaults (genserkins.h) where nothing sets a pin.
      const double h = kPi / 2;
      const std::array<double, 6> a0{0, 0, 300, 50, 0, 0}, alpha0{0, -h, 0, -h, h, -h},
          d0{0, 0, 70, 400, 0, 0};
      for (std::size_t i = 0; i < 6; ++i) {
        arm.a[i] = Pin(pins, module, fmt::format("A-{}", i), a0[i]);
        arm.alpha[i] = Pin(pins, module, fmt::format("ALPHA-{}", i), alpha0[i]);
        arm.d[i] = Pin(pins, module, fmt::format("D-{}", i), d0[i]);
        if (i > 0 && Pin(pins, module, fmt::format("unrotate-{}", i), 0.0) != 0.0) {
          throw Error(
              "{}: HAL sets genserkins.unrotate-{}: joints coupled to the previous one "
              "are not modelled",
              name_, i);
        }
      }
    }
    for (std::size_t i = 0; i < 6; ++i) {
      arm.a[i] *= length_;
      arm.d[i] *= length_;
    }
  }

  void ReadPivots(const std::string& module, MachineDescription* d) const {
    const HalPins pins = Pins(module);
    const auto pin = [&](const std::string& name, double fallback) {
      return Pin(pins, module, name, fallback);
    };
    if (module == "maxkins") {
      // Tilting head B (reversed), table C (reversed) about the machine's Z axis.
      d->head_length_mm = pin("pivot-length", 0.666) * length_;
      d->head_direction = -1.0;
      d->c_direction = -1.0;
      return;
    }
    const Eigen::Vector3d rot(pin("x-rot-point", 0.0), pin("y-rot-point", 0.0),
                              pin("z-rot-point", 0.0));
    const Eigen::Vector3d offset(
        d->kinematics == Kinematics::kXyzbcTrt ? pin("x-offset", 0.0) : 0.0,
        d->kinematics == Kinematics::kXyzacTrt ? pin("y-offset", 0.0) : 0.0, pin("z-offset", 0.0));
    d->c_pivot = rot * length_;
    d->tilt_pivot = (rot + offset) * length_;
  }

  IniFile ini_;
  std::string name_;
  MachineLoadOptions options_;
  double length_ = 1.0;         // machine units to mm
  double angle_ = kPi / 180.0;  // to rad
};

}  // namespace

MachineDescription ParseLinuxcncIni(std::string_view text, const std::string& source_name,
                                    const MachineLoadOptions& options) {
  return IniMachineReader(text, source_name, options).Read();
}

}  // namespace dtis::kinematics
