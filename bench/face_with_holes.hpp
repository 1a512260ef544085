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

// The same face as the floor of a pocket in a part of 55 other faces, all in one STEP file whose
// other faces the job checks (its default): a pin of 4 mm radius standing 10 mm tall in each
// hole, the pocket's four walls at the face's sides (the passes along y end 1 mm short of two of
// them), the part's top (220 x 140 mm at z = 10, the pocket's opening cut out of it) and on it,
// 20 to 80 mm beyond the pocket, 24 bosses (a side and a top each) the tool never comes near.
// Returns the job's path.
std::string WriteFaceWithHolesAmongOthersJob();

}  // namespace dtis::bench
