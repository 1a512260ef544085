// dtis' own B-spline kernel against OpenCASCADE's Geom_BSplineCurve on the same curve: the point
// (what the interpolator evaluates per step) and the point with three derivatives.
//   build/bench/dtis_bench --benchmark_filter=Curve
#include <benchmark/benchmark.h>

#include <random>

#include "dtis/geometry/occt_convert.hpp"
#include "dtis/io/curve_file.hpp"

namespace {

const dtis::geometry::BSplineCurve& Trident() {
  static const auto file =
      dtis::io::LoadCurveFile(std::string(DTIS_SOURCE_DIR) + "/samples/curves/trident.toml");
  return file.bottom;
}

std::vector<double> Parameters() {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> p(1024);
  for (auto& x : p) x = u(rng);
  return p;
}

void CurvePointDtis(benchmark::State& state) {
  const auto& c = Trident();
  const auto u = Parameters();
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(c.Point(u[i++ & 1023]));
}

void CurvePointOcct(benchmark::State& state) {
  const auto c = dtis::geometry::ToOcct(Trident());
  const auto u = Parameters();
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(c->Value(u[i++ & 1023]));
}

void CurveD3Dtis(benchmark::State& state) {
  const auto& c = Trident();
  const auto u = Parameters();
  std::size_t i = 0;
  Eigen::Vector3d d[4];
  for (auto _ : state) {
    c.Derivatives(u[i++ & 1023], 3, d);
    benchmark::DoNotOptimize(d);
  }
}

void CurveD3Occt(benchmark::State& state) {
  const auto c = dtis::geometry::ToOcct(Trident());
  const auto u = Parameters();
  std::size_t i = 0;
  gp_Pnt p;
  gp_Vec v1, v2, v3;
  for (auto _ : state) {
    c->D3(u[i++ & 1023], p, v1, v2, v3);
    benchmark::DoNotOptimize(v3);
  }
}

BENCHMARK(CurvePointDtis);
BENCHMARK(CurvePointOcct);
BENCHMARK(CurveD3Dtis);
BENCHMARK(CurveD3Occt);

}  // namespace
