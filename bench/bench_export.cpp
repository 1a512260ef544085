// The exports of `dtis compare` on the NURBS circle (R 50 mm, 314 mm), sampled every 0.01 mm as
// the comparison samples a pass: the chordal G1 discretization and the least-squares B-spline fit
// at 1 um.
//   build/bench/dtis_bench --benchmark_filter=Export
#include <benchmark/benchmark.h>

#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/path_fit.hpp"
#include "dtis/io/curve_file.hpp"

namespace {

const dtis::geometry::PathSamples& CircleSamples() {
  static const auto samples = [] {
    auto file =
        dtis::io::LoadCurveFile(std::string(DTIS_SOURCE_DIR) + "/samples/curves/nurbs_circle.toml");
    const dtis::geometry::CurvePath circle(std::move(file.bottom), Eigen::Vector3d::UnitZ());
    return dtis::geometry::SamplePath(circle, 0.01, "circle");
  }();
  return samples;
}

void ExportChordalCircle1um(benchmark::State& state) {
  const auto& s = CircleSamples();
  for (auto _ : state) {
    benchmark::DoNotOptimize(dtis::geometry::ChordalVertices(s, {0.001, 0.1, 100.0}));
  }
  state.counters["samples"] = static_cast<double>(s.Size());
}

void ExportFitCircle1um(benchmark::State& state) {
  const auto& s = CircleSamples();
  dtis::geometry::BSplineFitOptions o;
  o.tolerance.tip_mm = 0.001;
  long poles = 0;
  for (auto _ : state) {
    const auto fit = dtis::geometry::FitCubicBSpline(s, o, "circle");
    poles = static_cast<long>(fit.bottom.Poles().size());
    benchmark::DoNotOptimize(fit);
  }
  state.counters["poles"] = static_cast<double>(poles);
}

BENCHMARK(ExportChordalCircle1um)->Unit(benchmark::kMillisecond);
BENCHMARK(ExportFitCircle1um)->Unit(benchmark::kMillisecond);

}  // namespace
