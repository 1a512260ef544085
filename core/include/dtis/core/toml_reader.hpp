// Reading TOML input files (jobs, machines, curves) with messages that say file, line, key and
// what was expected. Every key a reader does not ask for is an error (RejectUnknown), so a typo is
// never silently ignored.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace toml {
inline namespace v3 {
class table;
class node;
}  // namespace v3
}  // namespace toml

namespace dtis {

// What a key that names things by number or by name holds: an integer, or a non-empty string.
struct IndexOrName {
  std::int64_t index = 0;  // when `name` is empty
  std::string name;
};

class TomlTable {
 public:
  // Parses a whole document. Throws dtis::Error "<file>: cannot open ..." or "<file>:<line>:<col>:
  // TOML syntax error: ...".
  static TomlTable ParseFile(const std::string& path);
  static TomlTable ParseString(std::string_view text, const std::string& source_name);

  TomlTable(TomlTable&&) noexcept;
  TomlTable& operator=(TomlTable&&) noexcept;
  ~TomlTable();

  const std::string& File() const { return *file_; }
  bool Has(std::string_view key) const;
  bool IsString(std::string_view key) const;

  double Number(std::string_view key);  // finite
  std::optional<double> OptionalNumber(std::string_view key);
  double PositiveNumber(std::string_view key);  // finite and > 0
  std::optional<double> OptionalPositiveNumber(std::string_view key);
  std::int64_t Integer(std::string_view key);
  std::optional<std::int64_t> OptionalInteger(std::string_view key);
  bool Boolean(std::string_view key);
  std::optional<bool> OptionalBoolean(std::string_view key);
  std::string String(std::string_view key);
  std::optional<std::string> OptionalString(std::string_view key);
  // One of `choices`; the error lists them.
  std::string Choice(std::string_view key, const std::vector<std::string>& choices);
  std::optional<std::string> OptionalChoice(std::string_view key,
                                            const std::vector<std::string>& choices);
  // One integer or string, or a non-empty array of them (`face = 3`, `face = ["floor", 4]`).
  std::optional<std::vector<IndexOrName>> OptionalIndicesOrNames(std::string_view key);
  std::vector<double> Numbers(std::string_view key);          // array of finite numbers
  std::vector<Eigen::Vector3d> Points(std::string_view key);  // array of [x, y] or [x, y, z]
  Eigen::Vector3d Point(std::string_view key);                // [x, y, z]
  std::optional<Eigen::Vector3d> OptionalPoint(std::string_view key);
  TomlTable Table(std::string_view key);
  std::optional<TomlTable> OptionalTable(std::string_view key);
  std::vector<std::string> Keys() const;

  // Throws for the first key no getter asked for, naming its line.
  void RejectUnknown() const;

  // "<file>:<line>: key '<path.key>': <message>" as a dtis::Error.
  [[noreturn]] void Fail(std::string_view key, const std::string& message) const;
  // The line of a key (0 if unknown) and its dotted path, for messages built elsewhere.
  int Line(std::string_view key) const;
  std::string KeyPath(std::string_view key) const;

 private:
  TomlTable(std::shared_ptr<void> document, const toml::table* table,
            std::shared_ptr<const std::string> file, std::string path);
  const toml::node* Get(std::string_view key);
  const toml::node& Require(std::string_view key);

  std::shared_ptr<void> document_;  // keeps the parsed document alive
  const toml::table* table_;
  std::shared_ptr<const std::string> file_;
  std::string path_;  // dotted path of this table ("" for the root)
  std::set<std::string, std::less<>> used_;
};

// A path named inside a file, resolved relative to that file's folder.
std::string ResolveRelative(const std::string& file, const std::string& path);

}  // namespace dtis
