// dtis' own B-spline surface kernel against OpenCASCADE's adaptor on the same face (trj8, degree
// 5 x 3; the rational WorkNC face): the point with its derivatives to order 2, which every Newton
// iteration of a surface pass evaluates. `walk` steps along a diagonal of the face by 1/4000 of it
// (a pass: the span cache holds), `random` jumps anywhere (a span set up per call).
//   build/bench/dtis_bench --benchmark_filter=SurfaceD2
#include <benchmark/benchmark.h>

#include <BRep_Tool.hxx>
#include <GeomAdaptor_Surface.hxx>
#include <random>

#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/step_model.hpp"

namespace {

const char* const kFaces[] = {"occt_trj8_c2-db-214_single_bspline_face.stp",
                              "occt_bug29478_single_rational_face_worknc.stp"};

const TopoDS_Face& Face(int which) {
  static const dtis::geometry::StepModel models[] = {
      dtis::geometry::StepModel::Load(std::string(DTIS_SOURCE_DIR) + "/samples/parts/" + kFaces[0]),
      dtis::geometry::StepModel::Load(std::string(DTIS_SOURCE_DIR) + "/samples/parts/" +
                                      kFaces[1])};
  static const TopoDS_Face faces[] = {models[0].Face(1), models[1].Face(1)};
  return faces[which];
}

// 4096 (u, v): a walk along the face's diagonal, or uniform at random.
std::vector<std::pair<double, double>> Parameters(const dtis::geometry::FaceSurface& s, bool walk) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> x(0.0, 1.0);
  std::vector<std::pair<double, double>> p(4096);
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double t = walk ? static_cast<double>(i) / 4000.0 : x(rng);
    const double w = walk ? 0.5 + 0.4 * std::sin(6.0 * t) : x(rng);
    p[i] = {s.U0() + (s.U1() - s.U0()) * std::min(t, 1.0), s.V0() + (s.V1() - s.V0()) * w};
  }
  return p;
}

void SurfaceD2Dtis(benchmark::State& state) {
  const dtis::geometry::FaceSurface s(Face(static_cast<int>(state.range(0))), "bench");
  if (!s.OwnKernel()) state.SkipWithError("not on dtis' kernel");
  const auto uv = Parameters(s, state.range(1) == 0);
  dtis::geometry::SurfaceDerivatives d;
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& [u, v] = uv[i++ & 4095];
    s.D2(u, v, &d);
    benchmark::DoNotOptimize(d);
  }
}

void SurfaceD2Occt(benchmark::State& state) {
  const dtis::geometry::FaceSurface face(Face(static_cast<int>(state.range(0))), "bench");
  const GeomAdaptor_Surface s(BRep_Tool::Surface(Face(static_cast<int>(state.range(0)))));
  const auto uv = Parameters(face, state.range(1) == 0);
  gp_Pnt p;
  gp_Vec su, sv, suu, svv, suv;
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& [u, v] = uv[i++ & 4095];
    s.D2(u, v, p, su, sv, suu, svv, suv);
    benchmark::DoNotOptimize(suv);
  }
}

void Cases(benchmark::internal::Benchmark* b) {
  b->ArgNames({"rational", "random"});
  for (int face : {0, 1}) {
    for (int random : {0, 1}) b->Args({face, random});
  }
}

BENCHMARK(SurfaceD2Dtis)->Apply(Cases);
BENCHMARK(SurfaceD2Occt)->Apply(Cases);

}  // namespace
