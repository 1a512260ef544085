// Reports: the limiter report read back, the face mesh drawn under a surface path, the
// report's data, and the static figures' decoding.
#include "dtis/io/report.hpp"

#include <gtest/gtest.h>

#include <BRepGProp.hxx>
#include <BRep_Tool.hxx>
#include <GProp_GProps.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "dtis/core/version.hpp"
#include "dtis/geometry/face_mesh.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/io/figures.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "test_support.hpp"

namespace dtis::io {
namespace {

using test::ExpectError;

const std::string kTrj8 = "samples/parts/occt_trj8_c2-db-214_single_bspline_face.stp";

TEST(Limiters, NamesReadBack) {
  for (int k = 0; k < static_cast<int>(interp::Limiter::kCount); ++k) {
    const auto limiter = static_cast<interp::Limiter>(k);
    EXPECT_EQ(interp::LimiterFromName(interp::LimiterName(limiter)), limiter);
  }
  EXPECT_EQ(interp::LimiterFromName("warp"), std::nullopt);
  EXPECT_EQ(interp::LimiterFromName(""), std::nullopt);
}

// Setpoints the verifier fails are written only when asked for: a jump of 1 mm in X on the line.
TEST(RunOutputs, SetpointsTheVerifierFailsAreNotWrittenUnlessKept) {
  const Job job = LoadJob(test::Source("samples/jobs/line.toml"));
  RunResult r = RunJob(job);
  ASSERT_TRUE(FitToWrite(job, r));
  auto& x = r.table.columns[0];
  for (std::size_t k = x.size() / 2; k < x.size(); ++k) x[k] += 1.0;
  r.verify = interp::Verify(r.table, *r.machine);
  ASSERT_FALSE(r.verify.Passed());
  EXPECT_FALSE(FitToWrite(job, r));
  const std::string setpoints = test::Scratch("failed.csv"),
                    limiters = test::Scratch("failed_l.csv");
  ExpectError([&] { WriteRunOutputs(job, r, setpoints, limiters); },
              "the verifier fails these setpoints (worst ratio");
  EXPECT_FALSE(std::filesystem::exists(setpoints));
  EXPECT_FALSE(std::filesystem::exists(limiters));
  WriteRunOutputs(job, r, setpoints, limiters, /*keep_failed=*/true);
  EXPECT_TRUE(std::filesystem::exists(setpoints));
  EXPECT_TRUE(std::filesystem::exists(limiters));
}

TEST(Limiters, ReportReadsBackWhatARunWrote) {
  const Job job = LoadJob(test::Source("samples/jobs/trident.toml"));
  const RunResult r = RunJob(job);
  const std::string setpoints = test::Scratch("limiters_run.csv");
  const std::string limiters = test::Scratch("limiters_run_lim.csv");
  WriteRunOutputs(job, r, setpoints, limiters);
  const auto back = ReadLimiters(limiters, AxisNames(*r.machine));
  ASSERT_EQ(back.size(), r.limiters.size());
  bool axis_seen = false;
  for (std::size_t k = 0; k < back.size(); ++k) {
    EXPECT_EQ(back[k].kind, r.limiters[k].kind) << "row " << k;
    EXPECT_EQ(back[k].axis, r.limiters[k].axis) << "row " << k;
    axis_seen = axis_seen || back[k].axis >= 0;
  }
  EXPECT_TRUE(axis_seen) << "the trident is limited by an axis somewhere";

  const std::vector<std::string> xyz{"X", "Y", "Z"};
  ExpectError([&] { ParseLimiters("t,X,Y,Z\n0,0,0,0\n", "l.csv", xyz); },
              "l.csv:1: expected the header 't,s,feed,limiter,axis'");
  ExpectError(
      [&] {
        ParseLimiters("t,s,feed,limiter,axis\n0,0,0,start,\n0.001,x,1,feed,\n", "l.csv", xyz);
      },
      "l.csv:3: column 2 ('s') is not a finite number");
  ExpectError([&] { ParseLimiters("t,s,feed,limiter,axis\n0,0,0,warp,\n", "l.csv", xyz); },
              "l.csv:2: column 4: unknown limiter 'warp'");
  ExpectError([&] { ParseLimiters("t,s,feed,limiter,axis\n0,0,0,axis_jerk,A\n", "l.csv", xyz); },
              "l.csv:2: column 5: 'A' is not an axis of the machine");
  ExpectError([&] { ParseLimiters("t,s,feed,limiter,axis\n0,0,0,feed\n", "l.csv", xyz); },
              "l.csv:2: 4 values; expected 5");
  ExpectError([&] { ParseLimiters("", "l.csv", xyz); }, "l.csv: empty file");
}

// Every node of a face's mesh is a point of the face (within the face's edge tolerance: boundary
// nodes come from the edges' 3D curves), the triangles' centroids are within the mesh's deflection
// of it, and the triangles cover its area, short of it as an inscribed mesh is. A placed face's
// mesh is checked against the placed face: a placement applied twice or not at all is far off.
void ExpectMeshOfFace(const TopoDS_Face& face) {
  const geometry::FaceMesh mesh = geometry::MeshFace(face, "trj8 face 1");
  ASSERT_GT(mesh.triangles.size(), 100u);
  const Handle(Geom_Surface) surface = BRep_Tool::Surface(face);  // with the face's location
  const auto distance = [&](const Eigen::Vector3d& p) {
    GeomAPI_ProjectPointOnSurf projection(gp_Pnt(p.x(), p.y(), p.z()), surface);
    return projection.NbPoints() > 0 ? projection.LowerDistance() : HUGE_VAL;
  };
  double node = 0.0, centroid = 0.0, area = 0.0;
  for (const auto& v : mesh.vertices) node = std::max(node, distance(v));
  for (const auto& t : mesh.triangles) {
    const auto& a = mesh.vertices[static_cast<std::size_t>(t[0])];
    const auto& b = mesh.vertices[static_cast<std::size_t>(t[1])];
    const auto& c = mesh.vertices[static_cast<std::size_t>(t[2])];
    centroid = std::max(centroid, distance((a + b + c) / 3.0));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  GProp_GProps props;
  BRepGProp::SurfaceProperties(face, props, 1e-9);
  EXPECT_LE(node, BRep_Tool::MaxTolerance(face, TopAbs_EDGE));
  EXPECT_LE(centroid, mesh.deflection_mm) << "deflection " << mesh.deflection_mm;
  EXPECT_LT(area, props.Mass());
  EXPECT_GT(area, 0.998 * props.Mass());
}

TEST(FaceMesh, LiesOnTheFaceAndCoversIt) {
  const auto model = geometry::StepModel::Load(test::Source(kTrj8));
  ExpectMeshOfFace(model.Face(1));
}

TEST(FaceMesh, FollowsThePlacement) {
  const auto model = geometry::StepModel::Load(test::Source(kTrj8));
  ExpectMeshOfFace(geometry::PlaceFace(model.Face(1), {0, 90, 0}, {10, 20, 30}));
}

nlohmann::json ReportData(const std::string& page) {
  const std::string key = "const DATA = ";
  const std::size_t at = page.find(key);
  EXPECT_NE(at, std::string::npos);
  const std::size_t end = page.find(";\n", at);
  return nlohmann::json::parse(page.substr(at + key.size(), end - at - key.size()));
}

// A report of run `r`: its machine, setpoints and verification.
ReportInput InputOf(const std::string& title, const RunResult& r) {
  ReportInput in;
  in.title = title;
  in.machine = r.machine.get();
  in.table = &r.table;
  in.verify = &r.verify;
  return in;
}

// The surface is drawn around the path only; a comparison adds its table and one feed curve per
// variant.
TEST(Report, DrawsTheFaceAroundThePathAndEveryVariant) {
  const Job job = LoadJob(test::Source("samples/jobs/line.toml"));  // X from 0 to 100 mm
  const RunResult r = RunJob(job);
  geometry::FaceMesh mesh;
  mesh.vertices = {{0, -1, 0},  {100, -1, 0}, {50, 1, 0},  // under the path
                   {0, 500, 0}, {1, 500, 0},  {0, 501, 0}};
  mesh.triangles = {{0, 1, 2}, {3, 4, 5}};
  CompareResult compare;
  for (const char* name : {"G1 10 um", "DTIS (exact surface)"}) {
    VariantResult v;
    v.name = name;
    v.table = r.table;
    v.verify = r.verify;
    compare.variants.push_back(v);
  }
  ReportInput in = InputOf("line", r);
  in.surface = &mesh;
  in.compare = &compare;
  in.shown = "DTIS (exact surface)";
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  EXPECT_EQ(data["surface"]["x"].size(), 3u);
  EXPECT_EQ(data["surface"]["i"].size(), 1u);
  ASSERT_EQ(data["compare"]["rows"].size(), 2u);
  // A page writes micrometres as such (the terminal's tables keep "um").
  EXPECT_EQ(data["compare"]["rows"][0][0], "G1 10 \u00b5m");
  EXPECT_EQ(data["compare"]["header"].size(), CompareHeader().size());
  EXPECT_EQ(data["compare"]["header"][7], "motion dev (\u00b5m)");
  ASSERT_EQ(data["compare"]["feeds"].size(), 2u);
  // Each feed series names its variant and the planner that planned it.
  EXPECT_EQ(data["compare"]["feeds"][1]["name"], "DTIS (exact surface) (vpop)");
  // The feed on the line peaks at the programmed 5 m/min.
  double peak = 0.0;
  for (const auto& f : data["compare"]["feeds"][0]["y"]) peak = std::max(peak, f.get<double>());
  EXPECT_NEAR(peak, 5000.0, 1e-6);
}

// The face is cut to the box around the path plus its margin: a triangle reaching out of it keeps
// the part inside, whose edge is the box's (not the jagged edge of whole triangles).
TEST(Report, CutsTheFaceStraightAtTheBoxAroundThePath) {
  const Job job = LoadJob(test::Source("samples/jobs/line.toml"));  // X from 0 to 100 mm
  const RunResult r = RunJob(job);
  const Eigen::Vector3d tip =
      r.machine
          ->Forward(
              FileUnits(*r.machine)
                  .ToPlanner({r.table.columns[0][0], r.table.columns[1][0], r.table.columns[2][0]}))
          .tip;
  // The path's box is 100 mm long: a margin of a quarter of that, 25 mm, all round.
  geometry::FaceMesh mesh;
  mesh.vertices = {
      {0, tip.y() - 1, tip.z()}, {100, tip.y() - 1, tip.z()}, {50, tip.y() + 100, tip.z()}};
  mesh.triangles = {{0, 1, 2}};
  ReportInput in = InputOf("line", r);
  in.surface = &mesh;
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  const auto& f = data["surface"];
  double area = 0.0, top = -HUGE_VAL;
  for (std::size_t t = 0; t < f["i"].size(); ++t) {
    Eigen::Vector3d p[3];
    for (int c = 0; c < 3; ++c) {
      const int v = f[std::string(1, "ijk"[c])][t];
      p[c] = Eigen::Vector3d(f["x"][v].get<double>(), f["y"][v].get<double>(),
                             f["z"][v].get<double>());
      top = std::max(top, p[c].y());
    }
    area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
  }
  // Below y = tip + 25 the triangle is a trapezoid 26 mm high, 100 mm wide at its base and
  // 100 * 75 / 101 mm at the cut.
  EXPECT_NEAR(top, tip.y() + 25.0, 1e-3);
  EXPECT_NEAR(area, 0.5 * (100.0 + 100.0 * 75.0 / 101.0) * 26.0, 0.05);
  // Its outline: the base, the two cut sides and the cut, as segments (two points and a gap).
  EXPECT_EQ(f["outline"]["x"].size(), 4u * 3u);
}

// How close each axis comes to its limits: the envelope peaks at the verifier's ratio for each
// derivative, and an axis has periods at a limit exactly when its ratio reaches kAtLimit.
TEST(Report, LimitUsagePeaksAtTheVerifiersRatios) {
  const Job job = LoadJob(test::Source("samples/jobs/surface_tilt10_xyzac.toml"));
  const RunResult r = RunJob(job);
  ReportInput in = InputOf(job.name, r);
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  ASSERT_EQ(data["axes"].size(), r.verify.axes.size());
  bool some_at_limit = false;
  for (std::size_t a = 0; a < r.verify.axes.size(); ++a) {
    const auto& axis = data["axes"][a];
    const auto& v = r.verify.axes[a];
    const double ratios[3] = {v.v_ratio, v.a_ratio, v.j_ratio};
    int d = 0;
    for (const char* name : {"velocity", "acceleration", "jerk"}) {
      double peak = 0.0;
      for (const auto& p : axis["usage"][name]["hi"]) peak = std::max(peak, p.get<double>());
      EXPECT_NEAR(peak, 100.0 * ratios[d], 1e-4 * peak + 1e-9) << v.name << " " << name;
      const double share = axis["at_limit"][d];
      if (ratios[d] >= kAtLimit) {
        EXPECT_GE(share, 100.0 / static_cast<double>(r.table.Rows())) << v.name << " " << name;
        some_at_limit = true;
      } else {
        EXPECT_EQ(share, 0.0) << v.name << " " << name;
      }
      ++d;
    }
  }
  EXPECT_TRUE(some_at_limit) << "a time-optimal plan has an axis at a limit";
}

// A surface job's feed is drawn along its passes: one span per pass, end to end, as long as the
// passes, and the time between two spans is a link's.
TEST(Report, FeedAlongThePassesLeavesTheLinksOut) {
  const Job job = LoadJob(test::Source("samples/jobs/surface_plane_cl_3axis.toml"));
  const RunResult r = RunJob(job);
  ASSERT_GT(r.passes, 10);
  ASSERT_EQ(r.pass_rows.size(), static_cast<std::size_t>(r.passes));
  ReportInput in = InputOf(job.name, r);
  in.limiters = r.limiters;
  in.pass_rows = r.pass_rows;
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  const auto& passes = data["pass_feed"]["passes"];
  ASSERT_EQ(passes.size(), r.pass_rows.size());
  double pass_time = 0.0;
  for (std::size_t k = 0; k < passes.size(); ++k) {
    EXPECT_LT(passes[k]["s0"].get<double>(), passes[k]["s1"].get<double>()) << k;
    pass_time += passes[k]["t1"].get<double>() - passes[k]["t0"].get<double>();
    if (k == 0) continue;
    EXPECT_EQ(passes[k]["s0"], passes[k - 1]["s1"]) << k;
    EXPECT_GT(passes[k]["t0"].get<double>(), passes[k - 1]["t1"].get<double>()) << k;
  }
  // The tip's chords along the passes against the passes' length: shorter, by far less than 0.1 %.
  const double along = passes.back()["s1"];
  EXPECT_LE(along, r.path_length_mm * (1 + 1e-9));
  EXPECT_GT(along, r.path_length_mm * (1 - 1e-3));
  // Each pass' rows span its motion time but for the periods at rest that end it.
  EXPECT_NEAR(pass_time, r.pass_motion_s, 4.5 * r.verify.period_s * r.passes);
  EXPECT_NEAR(data["pass_feed"]["link_time_s"].get<double>(), r.verify.motion_time_s - pass_time,
              1e-9);
  // The constraint band covers the passes only, within their span.
  ASSERT_FALSE(data["pass_feed"]["limiters"]["x"].empty());
  for (const auto& x : data["pass_feed"]["limiters"]["x"]) {
    EXPECT_GE(x.get<double>(), 0.0);
    EXPECT_LE(x.get<double>(), along);
  }
}

// The header names what the run is; the report adds the version of dtis that made it and when.
TEST(Report, HeaderNamesMachineJobPartFaceToolStrategyVersionAndDate) {
  const Job job = LoadJob(test::Source("samples/jobs/surface_tilt10_xyzac.toml"));
  const RunResult r = RunJob(job);
  ReportInput in = InputOf(job.name, r);
  in.about = JobFacts(job, *r.machine);
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  std::map<std::string, std::string> about;
  for (const auto& row : data["about"]) about[row[0]] = row[1];
  EXPECT_EQ(about["job"], job.file);
  EXPECT_NE(about["machine"].find(r.machine->Name()), std::string::npos);
  EXPECT_EQ(about["part"], job.surface->step_file);
  EXPECT_EQ(about["face"], "1");
  EXPECT_EQ(about["tool"], job.surface->tool.Describe());
  EXPECT_EQ(about["strategy"], "plane_cl");
  EXPECT_EQ(about["dtis"], std::string(kVersion));
  EXPECT_EQ(about["made"].size(), std::string("2026-11-24 20:16:05 +0000").size());
  EXPECT_EQ(data["about"].back()[0], "made");
}

// What RunOptions::progress hears: the phases in order; while planning, a share of the path that
// never goes back and ends whole, and the motion time planned, which ends at the plan's own.
struct Heard {
  std::vector<std::string> phases;
  std::map<std::string, std::vector<RunProgress>> reports;
};
Heard Listen(const std::string& job_file, RunResult* result) {
  Heard heard;
  RunOptions options;
  options.progress = [&heard](const RunProgress& p) {
    const std::string phase(p.phase);
    if (heard.phases.empty() || heard.phases.back() != phase) heard.phases.push_back(phase);
    heard.reports[phase].push_back(p);
  };
  *result = RunJob(LoadJob(test::Source(job_file)), options);
  return heard;
}
void ExpectForwardToTheEnd(const std::vector<RunProgress>& reports, double motion_s,
                           double tolerance_s = 1e-9) {
  ASSERT_FALSE(reports.empty());
  for (std::size_t k = 1; k < reports.size(); ++k) {
    EXPECT_GE(reports[k].fraction, reports[k - 1].fraction) << k;
    EXPECT_GE(reports[k].motion_s, reports[k - 1].motion_s) << k;
    EXPECT_GE(reports[k].segments_done, reports[k - 1].segments_done) << k;
  }
  EXPECT_GE(reports.front().fraction, 0.0);
  EXPECT_NEAR(reports.back().fraction, 1.0, 1e-9);
  EXPECT_NEAR(reports.back().motion_s, motion_s, tolerance_s);
  EXPECT_EQ(reports.back().segments_done, reports.back().segments);
}

TEST(Progress, ASurfaceJobNamesItsPhasesAndPlansToTheEnd) {
  RunResult r;
  const Heard heard = Listen("samples/jobs/surface_plane_cl_3axis.toml", &r);
  EXPECT_EQ(heard.phases,
            (std::vector<std::string>{"reading STEP", "tracing passes", "checking travel",
                                      "planning passes", "planning links", "verifying"}));
  // Each pass' time, to the periods at rest that end it.
  ExpectForwardToTheEnd(heard.reports.at("planning passes"), r.pass_motion_s,
                        4.5 * r.verify.period_s * r.passes);
  // The links' time counts on from the passes'; the whole is the program's, to the periods at
  // rest after its last move (the planner holds the rest a few periods).
  ExpectForwardToTheEnd(heard.reports.at("planning links"), r.verify.motion_time_s,
                        4.5 * r.verify.period_s);
  EXPECT_EQ(heard.reports.at("planning passes").back().segments, r.passes);
  // Within a pass, not only when one ends: more reports than passes.
  EXPECT_GT(heard.reports.at("planning passes").size(), static_cast<std::size_t>(r.passes) + 1);
}

TEST(Progress, ACurveMovesWithinItsOneSegment) {
  RunResult r;
  const Heard heard = Listen("samples/jobs/circle.toml", &r);
  EXPECT_EQ(heard.phases, (std::vector<std::string>{"planning", "verifying"}));
  const auto& planning = heard.reports.at("planning");
  // Reports at most 20 a second, but always the first and the last.
  ASSERT_GE(planning.size(), 2u);
  ExpectForwardToTheEnd({planning.front(), planning.back()}, r.vpop.motion_time_s);
}

TEST(Figures, Base64DecodesTheRfcVectors) {
  EXPECT_EQ(DecodeBase64(""), "");
  EXPECT_EQ(DecodeBase64("Zg=="), "f");
  EXPECT_EQ(DecodeBase64("Zm8="), "fo");
  EXPECT_EQ(DecodeBase64("Zm9v"), "foo");
  EXPECT_EQ(DecodeBase64("Zm9vYg=="), "foob");
  EXPECT_EQ(DecodeBase64("Zm9vYmE="), "fooba");
  EXPECT_EQ(DecodeBase64("Zm9vYmFy"), "foobar");
  EXPECT_EQ(DecodeBase64("Zm9v\nYmFy"), "foobar");
  EXPECT_EQ(DecodeBase64("/+8="), std::string("\xff\xef"));
  ExpectError([] { DecodeBase64("Zm9v!"); }, "unexpected character '!' at offset 4");
  ExpectError([] { DecodeBase64("Zm9vY"); }, "truncated");
  ExpectError([] { DecodeBase64("Zg==Zg=="); }, "unexpected character 'Z' at offset 4");
  ExpectError([] { DecodeBase64("Zh=="); }, "malformed");  // non-zero bits after the last byte
}

// A PNG's pHYs says its resolution: 300 dpi is 11811 dots per metre. The chunk's CRC is the one
// Python's zlib.crc32 gives for it.
TEST(Figures, PngsSayTheirDpi) {
  using namespace std::string_literals;
  const std::string signature = "\x89PNG\r\n\x1a\n"s;
  const std::string ihdr = "\0\0\0\x0dIHDR\0\0\0\x01\0\0\0\x01\x08\x00\0\0\0\x3a\x7e\x9b\x55"s;
  const std::string idat = "\0\0\0\0IDAT\x35\xaf\x06\x1e"s;
  const std::string iend = "\0\0\0\0IEND\xae\x42\x60\x82"s;
  const std::string phys =
      "\0\0\0\x09pHYs\0\0\x2e\x23\0\0\x2e\x23\x01\x78\xa5\x3f\x76"s;  // 300 dpi
  EXPECT_EQ(PngWithDpi(signature + ihdr + idat + iend, 300), signature + ihdr + phys + idat + iend);
  // One that had a resolution has the new one only.
  const std::string old_phys =
      "\0\0\0\x09pHYs\0\0\x0e\xc4\0\0\x0e\xc4\x01\x95\x2b\x0e\x1b"s;  // 96 dpi
  EXPECT_EQ(PngWithDpi(signature + ihdr + old_phys + idat + iend, 300),
            signature + ihdr + phys + idat + iend);
  ExpectError([] { PngWithDpi("GIF89a", 300); }, "not a PNG");
  ExpectError([&] { PngWithDpi(signature + ihdr.substr(0, 10), 300); }, "cut short");
}

TEST(Figures, SvgsCarryTheirSizeInMm) {
  EXPECT_EQ(
      SvgInMm(R"(<?xml?><svg class="main-svg" width="333" height="200"><g/></svg>)", 88, 52.9),
      R"(<?xml?><svg class="main-svg" width="88.00mm" height="52.90mm" viewBox="0 0 333 200"><g/></svg>)");
  EXPECT_EQ(SvgInMm(R"(<svg width="333" height="200" viewBox="0 0 333 200">)", 88, 52.9),
            R"(<svg width="88.00mm" height="52.90mm" viewBox="0 0 333 200">)");
  ExpectError([] { SvgInMm("<svg>", 88, 50); }, "no width and height");
  ExpectError([] { SvgInMm("<html>", 88, 50); }, "not an SVG");
}

TEST(Figures, ReadFromTheDomDump) {
  const std::string dom =
      R"(<div id="figures"><pre class="figure" data-name="path" data-format="png" data-width-mm="88" data-height-mm="70.4">iVBORw==</pre>)"
      R"(<pre class="figure" data-name="axis-X" data-format="svg">PHN2Zy8+</pre></div>)";
  const auto figures = ParseFigures(dom, "r.html");
  ASSERT_EQ(figures.size(), 2u);
  EXPECT_EQ(figures[0].name, "path");
  EXPECT_EQ(figures[0].format, "png");
  EXPECT_EQ(figures[0].bytes, "\x89PNG");
  EXPECT_EQ(figures[0].width_mm, 88.0);
  EXPECT_EQ(figures[0].height_mm, 70.4);
  EXPECT_EQ(figures[1].width_mm, 0.0);
  EXPECT_EQ(figures[1].name, "axis-X");
  EXPECT_EQ(figures[1].bytes, "<svg/>");
  ExpectError(
      [] { ParseFigures(R"(<pre class="figure" data-name="p" data-format="png">Zg==)", "r.html"); },
      "r.html: a figure element is not closed");
  ExpectError(
      [] {
        ParseFigures(R"(<pre class="figure" data-name="../x" data-format="png"></pre>)", "r.html");
      },
      "figure name '../x.png' is not a plain file name");
  ExpectError([] { ParseFigures(R"(<pre class="figure" data-format="png"></pre>)", "r.html"); },
              "a figure has no data-name");
  ExpectError(
      [] {
        ParseFigures(
            R"(<pre class="figure" data-name="p" data-format="png" data-width-mm="-3"></pre>)",
            "r.html");
      },
      "data-width-mm=\"-3\" is not a size in mm");
}

}  // namespace
}  // namespace dtis::io
