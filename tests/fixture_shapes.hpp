// Shapes the surface tests and the benchmarks make in code (no bundled part has them), and how
// they write them as STEP files.
#pragma once

#include <Geom_BSplineSurface.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <string>
#include <utility>
#include <vector>

namespace dtis::test {

// Ruled between z = 3 sin(2 pi y / 30) along x = 0 and the same wave a sixth of a period on along
// x = 60 (valleys of radius 7.6 mm), y in [0, 60]; u across (x = 60 u), v along.
Handle(Geom_BSplineSurface) WavyRuledSurface();
// The same as a face over its whole domain.
TopoDS_Face WavyRuledFace();

// Writes `shape` as a STEP file at `path`, quietly (OpenCASCADE's writer prints its statistics
// through the messenger). Throws std::runtime_error if it cannot.
void WriteStep(const TopoDS_Shape& shape, const std::string& path);

// Writes `faces` as one STEP file at `path`, each ADVANCED_FACE named as given (as a CAD system
// names them; "" leaves a face unnamed), and returns `path`. Throws std::runtime_error if it cannot.
std::string WriteNamedFaces(const std::vector<std::pair<TopoDS_Face, std::string>>& faces,
                            const std::string& path);

}  // namespace dtis::test
