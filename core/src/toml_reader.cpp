#include "dtis/core/toml_reader.hpp"

#include <toml++/toml.h>

#include <cmath>
#include <filesystem>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"

namespace dtis {
namespace {

std::string TypeName(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::table:
      return "a table";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a number";
    case toml::node_type::boolean:
      return "a boolean";
    default:
      return "a date or time";
  }
}

std::optional<double> AsNumber(const toml::node& node) {
  if (const auto* i = node.as_integer()) return static_cast<double>(i->get());
  if (const auto* f = node.as_floating_point()) return f->get();
  return std::nullopt;
}

}  // namespace

TomlTable::TomlTable(std::shared_ptr<void> document, const toml::table* table,
                     std::shared_ptr<const std::string> file, std::string path)
    : document_(std::move(document)),
      table_(table),
      file_(std::move(file)),
      path_(std::move(path)) {}
TomlTable::TomlTable(TomlTable&&) noexcept = default;
TomlTable& TomlTable::operator=(TomlTable&&) noexcept = default;
TomlTable::~TomlTable() = default;

TomlTable TomlTable::ParseString(std::string_view text, const std::string& source_name) {
  try {
    auto doc = std::make_shared<toml::table>(toml::parse(text, source_name));
    const toml::table* root = doc.get();
    return TomlTable(std::move(doc), root, std::make_shared<const std::string>(source_name), "");
  } catch (const toml::parse_error& e) {
    throw Error("{}:{}:{}: TOML syntax error: {}", source_name, e.source().begin.line,
                e.source().begin.column, e.description());
  }
}

TomlTable TomlTable::ParseFile(const std::string& path) {
  const std::optional<std::string> text = ReadFileText(path);
  if (!text) {
    std::error_code ec;
    const bool exists = std::filesystem::exists(path, ec);
    throw Error("{}: cannot open ({}); check the path", path,
                exists ? "permission denied or not a file" : "no such file");
  }
  return ParseString(*text, path);
}

bool TomlTable::Has(std::string_view key) const { return table_->contains(key); }

bool TomlTable::IsString(std::string_view key) const {
  const toml::node* n = table_->get(key);
  return n && n->is_string();
}

std::string TomlTable::KeyPath(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

int TomlTable::Line(std::string_view key) const {
  if (const toml::node* n = table_->get(key)) return static_cast<int>(n->source().begin.line);
  return static_cast<int>(table_->source().begin.line);
}

void TomlTable::Fail(std::string_view key, const std::string& message) const {
  throw Error("{}:{}: key '{}': {}", *file_, Line(key), KeyPath(key), message);
}

const toml::node* TomlTable::Get(std::string_view key) {
  used_.emplace(key);
  return table_->get(key);
}

const toml::node& TomlTable::Require(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) {
    throw Error("{}:{}: missing key '{}'{}", *file_, table_->source().begin.line, KeyPath(key),
                path_.empty() ? "" : fmt::format(" in table [{}]", path_));
  }
  return *n;
}

std::optional<double> TomlTable::OptionalNumber(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto v = AsNumber(*n);
  if (!v) Fail(key, "expected a number, got " + TypeName(*n));
  if (!std::isfinite(*v)) Fail(key, fmt::format("expected a finite number, got {}", *v));
  return v;
}

double TomlTable::Number(std::string_view key) {
  Require(key);
  return *OptionalNumber(key);
}

std::optional<double> TomlTable::OptionalPositiveNumber(std::string_view key) {
  const auto v = OptionalNumber(key);
  if (v && !(*v > 0.0)) Fail(key, fmt::format("expected a number > 0, got {}", *v));
  return v;
}

double TomlTable::PositiveNumber(std::string_view key) {
  Require(key);
  return *OptionalPositiveNumber(key);
}

std::optional<std::int64_t> TomlTable::OptionalInteger(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto* i = n->as_integer();
  if (!i) Fail(key, "expected an integer, got " + TypeName(*n));
  return i->get();
}

std::int64_t TomlTable::Integer(std::string_view key) {
  Require(key);
  return *OptionalInteger(key);
}

std::optional<bool> TomlTable::OptionalBoolean(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto* b = n->as_boolean();
  if (!b) Fail(key, "expected true or false, got " + TypeName(*n));
  return b->get();
}

bool TomlTable::Boolean(std::string_view key) {
  Require(key);
  return *OptionalBoolean(key);
}

std::optional<std::string> TomlTable::OptionalString(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto* s = n->as_string();
  if (!s) Fail(key, "expected a string, got " + TypeName(*n));
  return s->get();
}

std::string TomlTable::String(std::string_view key) {
  Require(key);
  return *OptionalString(key);
}

std::optional<std::string> TomlTable::OptionalChoice(std::string_view key,
                                                     const std::vector<std::string>& choices) {
  const auto s = OptionalString(key);
  if (!s) return s;
  for (const auto& c : choices) {
    if (c == *s) return s;
  }
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "'" : ", '") + c + "'";
  Fail(key, fmt::format("'{}' is not one of {}", *s, list));
}

std::string TomlTable::Choice(std::string_view key, const std::vector<std::string>& choices) {
  Require(key);
  return *OptionalChoice(key, choices);
}

std::optional<std::vector<IndexOrName>> TomlTable::OptionalIndicesOrNames(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto one = [&](const toml::node& item, const std::string& what) {
    if (const auto* i = item.as_integer()) return IndexOrName{i->get(), {}};
    if (const auto* s = item.as_string()) {
      if (s->get().empty()) Fail(key, what + "is an empty string; expected a name");
      return IndexOrName{0, s->get()};
    }
    Fail(key, what + "is " + TypeName(item) + "; expected an integer or a string");
  };
  std::vector<IndexOrName> items;
  if (const auto* array = n->as_array()) {
    if (array->empty()) Fail(key, "expected an integer, a string or an array of them, got []");
    for (std::size_t i = 0; i < array->size(); ++i) {
      items.push_back(one(*array->get(i), fmt::format("element {} ", i + 1)));
    }
  } else {
    items.push_back(one(*n, "the value "));
  }
  return items;
}

std::vector<double> TomlTable::Numbers(std::string_view key) {
  const toml::node& n = Require(key);
  const auto* array = n.as_array();
  if (!array) Fail(key, "expected an array of numbers, got " + TypeName(n));
  std::vector<double> values;
  values.reserve(array->size());
  for (std::size_t i = 0; i < array->size(); ++i) {
    const auto v = AsNumber(*array->get(i));
    if (!v || !std::isfinite(*v)) {
      Fail(key, fmt::format("element {} is not a finite number", i));
    }
    values.push_back(*v);
  }
  return values;
}

std::vector<Eigen::Vector3d> TomlTable::Points(std::string_view key) {
  const toml::node& n = Require(key);
  const auto* array = n.as_array();
  if (!array) Fail(key, "expected an array of points [x, y] or [x, y, z], got " + TypeName(n));
  std::vector<Eigen::Vector3d> points;
  points.reserve(array->size());
  for (std::size_t i = 0; i < array->size(); ++i) {
    const auto* p = array->get(i)->as_array();
    if (!p || (p->size() != 2 && p->size() != 3)) {
      Fail(key, fmt::format("point {} is not [x, y] or [x, y, z]", i));
    }
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < p->size(); ++k) {
      const auto v = AsNumber(*p->get(k));
      if (!v || !std::isfinite(*v)) {
        Fail(key, fmt::format("point {} coordinate {} is not a finite number", i, k));
      }
      point[static_cast<Eigen::Index>(k)] = *v;
    }
    points.push_back(point);
  }
  return points;
}

std::optional<Eigen::Vector3d> TomlTable::OptionalPoint(std::string_view key) {
  if (!Has(key)) {
    used_.emplace(key);
    return std::nullopt;
  }
  const auto values = Numbers(key);
  if (values.size() != 3) {
    Fail(key, fmt::format("expected [x, y, z], got {} numbers", values.size()));
  }
  return Eigen::Vector3d(values[0], values[1], values[2]);
}

Eigen::Vector3d TomlTable::Point(std::string_view key) {
  Require(key);
  return *OptionalPoint(key);
}

std::optional<TomlTable> TomlTable::OptionalTable(std::string_view key) {
  const toml::node* n = Get(key);
  if (!n) return std::nullopt;
  const auto* t = n->as_table();
  if (!t) Fail(key, "expected a table, got " + TypeName(*n));
  return TomlTable(document_, t, file_, KeyPath(key));
}

TomlTable TomlTable::Table(std::string_view key) {
  Require(key);
  return std::move(*OptionalTable(key));
}

std::vector<std::string> TomlTable::Keys() const {
  std::vector<std::string> keys;
  for (const auto& [k, v] : *table_) keys.emplace_back(k.str());
  return keys;
}

void TomlTable::RejectUnknown() const {
  for (const auto& [k, v] : *table_) {
    if (!used_.contains(k.str())) {
      throw Error("{}:{}: unknown key '{}'; check its spelling against the documentation", *file_,
                  v.source().begin.line, KeyPath(k.str()));
    }
  }
}

std::string ResolveRelative(const std::string& file, const std::string& path) {
  const std::filesystem::path p(path);
  if (p.is_absolute()) return path;
  return (std::filesystem::path(file).parent_path() / p).lexically_normal().string();
}

}  // namespace dtis
