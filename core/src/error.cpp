#include "dtis/core/error.hpp"

namespace dtis {

std::string Exact(double value) { return fmt::format("{}", value); }

}  // namespace dtis
