// A trimmed B-spline face with holes for the benchmarks, made in code: no such face is among the
// bundled parts.
#pragma once

#include <string>

namespace dtis::bench {

// Writes a wavy ruled B-spline face (60 x 60 mm, waves of 3 mm amplitude over 30 mm) with two
// round holes of 6 mm radius as a STEP file, and a plane_cl job on it (1 mm ball end, stepover
// 3 mm, F 3 m/min, the XYZ Mikron), into a folder of this process's own under the system's
// temporary folder (removed at exit). Returns the job's path.
std::string WriteFaceWithHolesJob();

}  // namespace dtis::bench
