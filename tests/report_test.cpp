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
  ReportInput in;
  in.title = "line";
  in.machine = r.machine.get();
  in.table = &r.table;
  in.verify = &r.verify;
  in.surface = &mesh;
  in.compare = &compare;
  in.shown = "DTIS (exact surface)";
  const nlohmann::json data = ReportData(RenderReport(in, "/* plotly */"));
  EXPECT_EQ(data["surface"]["x"].size(), 3u);
  EXPECT_EQ(data["surface"]["i"].size(), 1u);
  ASSERT_EQ(data["compare"]["rows"].size(), 2u);
  EXPECT_EQ(data["compare"]["rows"][0][0], "G1 10 um");
  EXPECT_EQ(data["compare"]["header"].size(), CompareHeader().size());
  ASSERT_EQ(data["compare"]["feeds"].size(), 2u);
  // Each feed series names its variant and the planner that planned it.
  EXPECT_EQ(data["compare"]["feeds"][1]["name"], "DTIS (exact surface) (vpop)");
  // The feed on the line peaks at the programmed 5 m/min.
  double peak = 0.0;
  for (const auto& f : data["compare"]["feeds"][0]["y"]) peak = std::max(peak, f.get<double>());
  EXPECT_NEAR(peak, 5000.0, 1e-6);
}

// The header names what the run is; the report adds the version of dtis that made it and when.
TEST(Report, HeaderNamesMachineJobPartFaceToolStrategyVersionAndDate) {
  const Job job = LoadJob(test::Source("samples/jobs/surface_tilt10_xyzac.toml"));
  const RunResult r = RunJob(job);
  ReportInput in;
  in.title = job.name;
  in.machine = r.machine.get();
  in.table = &r.table;
  in.verify = &r.verify;
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

TEST(Figures, ReadFromTheDomDump) {
  const std::string dom =
      R"(<div id="figures"><pre class="figure" data-name="path" data-format="png">iVBORw==</pre>)"
      R"(<pre class="figure" data-name="axis-X" data-format="svg">PHN2Zy8+</pre></div>)";
  const auto figures = ParseFigures(dom, "r.html");
  ASSERT_EQ(figures.size(), 2u);
  EXPECT_EQ(figures[0].name, "path");
  EXPECT_EQ(figures[0].format, "png");
  EXPECT_EQ(figures[0].bytes, "\x89PNG");
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
}

}  // namespace
}  // namespace dtis::io
