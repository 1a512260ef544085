#include "dtis/core/file_text.hpp"

#include <fstream>
#include <sstream>

namespace dtis {

std::optional<std::string> ReadFileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream text;
  text << in.rdbuf();
  return std::move(text).str();
}

}  // namespace dtis
