// dtis_min_time: the minimum motion time of a job's path under its machine's axis limits, computed
// independently of dtis' planners as a nonlinear program (IPOPT), for the reference figures in
// docs/references.md.
//
// The problem is the one the verifier checks, in discrete time: arc lengths s_1 .. s_{N-1} at a
// common period h (free), s_0 = 0 and s_N = L with the path held at rest before and after
// (s_{-2} = s_{-1} = 0, s_{N+1} = s_{N+2} = L). For every row k and axis i, the backward
// differences of the exact axis positions q_i(s_k) (Beudaert 2012, Eq. 6 and 14) stay within the
// limits: |D1 q| <= V h, |D2 q| <= A h^2, |D3 q| <= J h^3; the feed 0 <= s_k - s_{k-1} <= F h.
// Minimise N h. The positions come from the job's PathSource and Machine (dq/ds by central
// differences of exact positions); nothing of the planners is used but a feasible starting point,
// which the NLP then improves. A second solve with N = round(T / period) brings h back to about
// the job's period.
//
// A surface job of one pass (max_passes = 1, or a face and strategy that make one) is solved on
// that pass, with the pass's own options (its feed, the job's period).
//
//   dtis_min_time samples/jobs/trident.toml [--feed-mm-min 5000]
//   dtis_min_time samples/jobs/surface_tilt10_xyzac.toml
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <coin/IpIpoptApplication.hpp>
#include <coin/IpTNLP.hpp>
#include <cstdio>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/atomic_file.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/stream.hpp"
#include "dtis/kinematics/machines.hpp"

namespace {

using Ipopt::Index;
using Ipopt::Number;

struct Collect final : dtis::interp::SetpointSink {
  std::vector<double> s;
  dtis::AxisVector first_q;  // the axes at the start, which pick the rotary axes' branch
  void Accept(const dtis::interp::Setpoint& sp) override {
    if (s.empty()) first_q = sp.q;
    s.push_back(sp.s);
  }
};

// Axis positions along the path, with their derivative by central differences.
class Positions {
 public:
  // `start_q`: the axes at the path's start, which select the inverse's branch.
  Positions(const dtis::PathSource& path, const dtis::Machine& machine,
            const dtis::AxisVector& start_q)
      : path_(path), machine_(machine), n_(machine.AxisCount()), start_q_(start_q) {}
  int Axes() const { return n_; }
  // Where a march along the path starts (a surface pass's Newton needs a state on the pass).
  dtis::PathState Start() const { return path_.Start(); }
  // q(s) and dq/ds(s); `hint` keeps the state of the last evaluation near s, `near` the axes
  // there (they pick the rotary axes' branch).
  void At(double s, dtis::PathState* hint, const dtis::AxisVector& near, dtis::AxisVector* q,
          dtis::AxisVector* dq) const {
    const double length = *path_.Length();
    const double eps = 1e-5;
    s = std::clamp(s, 0.0, length);
    const double a = std::max(0.0, s - eps), b = std::min(length, s + eps);
    const auto eval = [&](double x, dtis::AxisVector* out) {
      const dtis::PathSample p = path_.At(*hint, x);
      *hint = p.state;
      const dtis::InverseResult r = machine_.Inverse(p.pose, &near, out);
      if (r.status != dtis::InverseStatus::kOk) {
        throw dtis::Error("at s = {} mm: {}", x, dtis::DescribeInverseFailure(machine_, r));
      }
    };
    dtis::AxisVector qa, qb;
    eval(a, &qa);
    eval(b, &qb);
    eval(s, q);
    *dq = (qb - qa) / (b - a);
  }
  const dtis::AxisVector& StartAxes() const { return start_q_; }

 private:
  const dtis::PathSource& path_;
  const dtis::Machine& machine_;
  int n_;
  dtis::AxisVector start_q_;
};

// Variables: s_1 .. s_{N-1}, then h in ms.
class MinTime final : public Ipopt::TNLP {
 public:
  MinTime(const Positions& q, const dtis::Machine& machine, double length, double feed,
          std::vector<double> s0, double h0_ms)
      : q_(q), length_(length), feed_(feed), start_(std::move(s0)), h0_(h0_ms) {
    N_ = static_cast<int>(start_.size()) - 1;  // s_0 .. s_N
    for (const auto& a : machine.Axes()) limits_.push_back({a.vmax, a.amax, a.jmax});
    states_.assign(start_.size(), q_.Start());
  }
  std::vector<double> solution;
  double solution_h_ms = 0.0;

  // Rows k = 1 .. N + 2; per row: per axis the three orders, then the feed.
  int PerRow() const { return 3 * q_.Axes() + 1; }
  int Rows() const { return N_ + 2; }

  bool get_nlp_info(Index& n, Index& m, Index& nnz_jac_g, Index& nnz_h_lag,
                    IndexStyleEnum& index_style) override {
    n = N_;  // N - 1 arc lengths and h
    m = Rows() * PerRow();
    nnz_jac_g = 0;
    ForEachEntry([&](int, int, double) { ++nnz_jac_g; }, nullptr);
    nnz_h_lag = 0;
    index_style = C_STYLE;
    return true;
  }
  bool get_bounds_info(Index n, Number* x_l, Number* x_u, Index m, Number* g_l,
                       Number* g_u) override {
    // The feed rows (>= 0) keep the arc lengths between s_0 = 0 and s_N = length at every
    // feasible point; the bounds only keep iterates near the path (positions are clamped to it).
    // Bounds at 0 and the length would have IPOPT push the start inside them by 1 % of the
    // length (bound_push), off the planner's motion: rows at rest at the end moved 0.13 mm back
    // on a 13 mm surface pass, a jerk 336 000 times its limit to start from.
    const double margin = 1.0 + 0.1 * length_;
    for (Index k = 0; k < n - 1; ++k) x_l[k] = -margin, x_u[k] = length_ + margin;
    x_l[n - 1] = 1e-3 * h0_, x_u[n - 1] = 10.0 * h0_;
    for (Index r = 0; r < m; ++r) {
      const bool feed_row = (r % PerRow()) == PerRow() - 1;
      g_l[r] = feed_row ? 0.0 : -1.0;
      g_u[r] = 1.0;
    }
    return true;
  }
  bool get_starting_point(Index n, bool, Number* x, bool, Number*, Number*, Index, bool,
                          Number*) override {
    for (Index k = 0; k < n - 1; ++k) x[k] = start_[static_cast<std::size_t>(k + 1)];
    x[n - 1] = h0_;
    return true;
  }
  bool eval_f(Index n, const Number* x, bool, Number& f) override {
    f = N_ * x[n - 1] * 1e-3;  // motion time, s
    return true;
  }
  bool eval_grad_f(Index n, const Number*, bool, Number* g) override {
    std::fill(g, g + n, 0.0);
    g[n - 1] = N_ * 1e-3;
    return true;
  }
  bool eval_g(Index, const Number* x, bool new_x, Index m, Number* g) override {
    if ((new_x || !evaluated_) && !TryEvaluate(x)) return false;
    for (Index r = 0; r < m; ++r) g[r] = values_[static_cast<std::size_t>(r)];
    return true;
  }
  bool eval_jac_g(Index, const Number* x, bool new_x, Index, Index, Index* rows, Index* cols,
                  Number* values) override {
    int e = 0;
    if (!values) {
      ForEachEntry(
          [&](int r, int c, double) {
            rows[e] = r;
            cols[e] = c;
            ++e;
          },
          nullptr);
      return true;
    }
    if ((new_x || !evaluated_) && !TryEvaluate(x)) return false;
    ForEachEntry([&](int, int, double v) { values[e++] = v; }, x);
    return true;
  }
  void finalize_solution(Ipopt::SolverReturn, Index n, const Number* x, const Number*,
                         const Number*, Index, const Number*, const Number*, Number,
                         const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    solution.assign(static_cast<std::size_t>(N_) + 1, 0.0);
    solution[0] = 0.0;
    for (Index k = 0; k < n - 1; ++k) solution[static_cast<std::size_t>(k + 1)] = x[k];
    solution[static_cast<std::size_t>(N_)] = length_;
    solution_h_ms = x[n - 1];
  }

 private:
  struct Limits {
    double v, a, j;
  };
  // s at row index k (-2 .. N + 2) from the variables.
  double S(const Number* x, int k) const {
    if (k <= 0) return 0.0;
    if (k >= N_) return length_;
    return x[k - 1];
  }
  static bool IsVariable(int k, int N) { return k >= 1 && k <= N - 1; }

  // Evaluate, or false (the reason on stderr) where the path or the machine refuses a point:
  // IPOPT then tries a shorter step.
  bool TryEvaluate(const Number* x) {
    try {
      Evaluate(x);
      return true;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "dtis_min_time: an evaluation failed: %s\n", e.what());
      evaluated_ = false;
      return false;
    }
  }

  void Evaluate(const Number* x) {
    const int n = q_.Axes();
    qs_.resize(static_cast<std::size_t>(N_) + 1);
    dqs_.resize(static_cast<std::size_t>(N_) + 1);
    for (int k = 0; k <= N_; ++k) {
      const auto i = static_cast<std::size_t>(k);
      // The first evaluation marches along the rows in order, each from the one before.
      if (!marched_ && k > 0) states_[i] = states_[i - 1];
      const dtis::AxisVector near = marched_ ? qs_[i] : (k > 0 ? qs_[i - 1] : q_.StartAxes());
      q_.At(S(x, k), &states_[i], near, &qs_[i], &dqs_[i]);
    }
    marched_ = true;
    const double h = x[N_ - 1] * 1e-3;
    values_.assign(static_cast<std::size_t>(Rows() * PerRow()), 0.0);
    const auto Q = [&](int k) -> const dtis::AxisVector& {
      return qs_[static_cast<std::size_t>(std::clamp(k, 0, N_))];
    };
    for (int k = 1; k <= N_ + 2; ++k) {
      const std::size_t base = static_cast<std::size_t>((k - 1) * PerRow());
      for (int i = 0; i < n; ++i) {
        const Limits& l = limits_[static_cast<std::size_t>(i)];
        const double d1 = Q(k)[i] - Q(k - 1)[i];
        const double d2 = Q(k)[i] - 2 * Q(k - 1)[i] + Q(k - 2)[i];
        const double d3 = Q(k)[i] - 3 * Q(k - 1)[i] + 3 * Q(k - 2)[i] - Q(k - 3)[i];
        values_[base + static_cast<std::size_t>(3 * i)] = d1 / h / l.v;
        values_[base + static_cast<std::size_t>(3 * i + 1)] = d2 / (h * h) / l.a;
        values_[base + static_cast<std::size_t>(3 * i + 2)] = d3 / (h * h * h) / l.j;
      }
      values_[base + static_cast<std::size_t>(3 * n)] = (S(x, k) - S(x, k - 1)) / h / feed_;
    }
    evaluated_ = true;
  }

  // Calls f(row, column, value) for every structural non-zero of the Jacobian, in a fixed order;
  // values only when x is given (after Evaluate(x)).
  template <typename F>
  void ForEachEntry(F&& f, const Number* x) const {
    const int n = q_.Axes();
    const int hcol = N_ - 1;
    const double h = x ? x[hcol] * 1e-3 : 1.0;
    static constexpr double kCoef[3][4] = {{1, -1, 0, 0}, {1, -2, 1, 0}, {1, -3, 3, -1}};
    for (int k = 1; k <= N_ + 2; ++k) {
      const int base = (k - 1) * PerRow();
      for (int i = 0; i < n; ++i) {
        const Limits& l = limits_[static_cast<std::size_t>(i)];
        for (int order = 0; order < 3; ++order) {
          const int row = base + 3 * i + order;
          const double limit = order == 0 ? l.v : order == 1 ? l.a : l.j;
          const double scale = 1.0 / (std::pow(h, order + 1) * limit);
          for (int m = 0; m <= order + 1; ++m) {
            const int kk = k - m;
            if (!IsVariable(kk, N_)) continue;
            const double v =
                x ? kCoef[order][m] * dqs_[static_cast<std::size_t>(kk)][i] * scale : 0.0;
            f(row, kk - 1, v);
          }
          // d/dh of D / h^(order+1): -(order + 1) g / h, h in ms.
          const double g = x ? values_[static_cast<std::size_t>(row)] : 0.0;
          f(row, hcol, -(order + 1) * g / (h * 1e3));
        }
      }
      const int row = base + 3 * n;
      for (int m = 0; m <= 1; ++m) {
        const int kk = k - m;
        if (!IsVariable(kk, N_)) continue;
        f(row, kk - 1, x ? (m == 0 ? 1.0 : -1.0) / (h * feed_) : 0.0);
      }
      const double g = x ? values_[static_cast<std::size_t>(row)] : 0.0;
      f(row, hcol, -g / (h * 1e3));
    }
  }

  const Positions& q_;
  double length_, feed_;
  std::vector<double> start_;
  double h0_;
  int N_ = 0;
  std::vector<Limits> limits_;
  std::vector<dtis::PathState> states_;
  bool marched_ = false;
  std::vector<dtis::AxisVector> qs_, dqs_;
  std::vector<double> values_;
  bool evaluated_ = false;
};

// s(t) of `s` (period h) resampled to n + 1 points over the same time.
std::vector<double> Resample(const std::vector<double>& s, int n) {
  std::vector<double> out(static_cast<std::size_t>(n) + 1);
  const double last = static_cast<double>(s.size() - 1);
  for (int k = 0; k <= n; ++k) {
    const double t = last * k / n;
    const auto i = static_cast<std::size_t>(std::min(std::floor(t), last - 1));
    const double f = t - static_cast<double>(i);
    out[static_cast<std::size_t>(k)] = s[i] + f * (s[i + 1] - s[i]);
  }
  out.back() = s.back();
  return out;
}

struct Solved {
  std::vector<double> s;
  double h_ms;
  Ipopt::ApplicationReturnStatus status;
};

Solved Solve(const Positions& q, const dtis::Machine& machine, double length, double feed,
             std::vector<double> start, double h_ms, int max_iter, bool verbose) {
  Ipopt::SmartPtr<MinTime> nlp = new MinTime(q, machine, length, feed, std::move(start), h_ms);
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  app->Options()->SetStringValue("hessian_approximation", "limited-memory");
  app->Options()->SetNumericValue("tol", 1e-9);
  app->Options()->SetNumericValue("constr_viol_tol", 1e-9);
  app->Options()->SetIntegerValue("max_iter", max_iter);
  app->Options()->SetIntegerValue("print_level", verbose ? 5 : 0);
  app->Options()->SetStringValue("sb", "yes");
  if (app->Initialize() != Ipopt::Solve_Succeeded) throw dtis::Error("IPOPT failed to start");
  const auto status = app->OptimizeTNLP(Ipopt::SmartPtr<Ipopt::TNLP>(GetRawPtr(nlp)));
  return {nlp->solution, nlp->solution_h_ms, status};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"minimum motion time of a job's path (reference figures, IPOPT)"};
  std::string job_file, out, arc_out;
  double feed_mm_min = 0.0;
  int max_iter = 3000;
  bool verbose = false;
  app.add_option("job", job_file, "job file (line, curve, or a surface job of one pass)")
      ->required();
  app.add_option("--feed-mm-min", feed_mm_min, "programmed feed instead of the job's");
  app.add_option("-o", out, "write the optimal setpoints (CSV) here");
  app.add_option("--arc-length", arc_out, "write the arc length of each row (one per line) here");
  app.add_option("--max-iter", max_iter, "IPOPT iterations per solve");
  app.add_flag("-v", verbose, "IPOPT's iteration log");
  CLI11_PARSE(app, argc, argv);
  try {
    auto job = dtis::io::LoadJob(job_file);
    if (feed_mm_min > 0.0) job.vpop.feed_mm_s = feed_mm_min / 60.0;
    const auto machine = dtis::io::LoadJobMachine(job);
    std::shared_ptr<const dtis::PathSource> path;
    dtis::interp::VpopOptions o = job.vpop;
    std::unique_ptr<dtis::io::SegmentSource> segments;  // holds the face the pass is traced on
    if (job.surface) {
      // The job's one pass, traced as `dtis run` traces it.
      segments = dtis::io::JobSegments(job, *machine);
      std::optional<dtis::io::StreamSegment> pass = segments->Next(std::nullopt);
      if (!pass || pass->pass < 0 || segments->Next(std::nullopt)) {
        throw dtis::Error(
            "{}: dtis_min_time solves a surface job of one pass (set [strategy] max_passes = 1)",
            job.file);
      }
      path = pass->path;
      o = pass->options;
      if (feed_mm_min > 0.0) o.feed_mm_s = feed_mm_min / 60.0;
    } else {
      path = dtis::io::BuildPath(job);
    }
    path->Reach(INFINITY);
    if (!path->Length()) throw dtis::Error("{}: the path's length is not known", job.file);
    const double length = *path->Length();
    const double dt = o.period_s;

    // A feasible start: the job's planner (any feasible sequence would do).
    Collect planned;
    dtis::interp::PlanVpop(*path, *machine, o, planned);
    std::vector<double> s = planned.s;
    while (s.size() > 2 && s[s.size() - 2] == length) s.pop_back();
    const double start_time = static_cast<double>(s.size() - 1) * dt;

    const Positions q(*path, *machine, planned.first_q);
    Solved a = Solve(q, *machine, length, o.feed_mm_s, s, dt * 1e3, max_iter, verbose);
    const double t1 = static_cast<double>(a.s.size() - 1) * a.h_ms * 1e-3;
    // Again with about the job's period.
    const int n2 = static_cast<int>(std::lround(t1 / dt));
    Solved b = Solve(q, *machine, length, o.feed_mm_s, Resample(a.s, n2), t1 / n2 * 1e3, max_iter,
                     verbose);
    const double h = b.h_ms * 1e-3;
    const double t2 = n2 * h;

    // The verifier on the result, at its own period.
    dtis::io::TableSink table(*machine, h);
    dtis::PathState st = path->Start();
    dtis::AxisVector last;
    long index = 0;
    const auto emit = [&](double sk) {
      const auto p = path->At(st, sk);
      st = p.state;
      dtis::interp::Setpoint sp;
      sp.index = index++;
      sp.s = sk;
      machine->Inverse(p.pose, index > 1 ? &last : nullptr, &sp.q);
      last = sp.q;
      table.Accept(sp);
    };
    for (const double sk : b.s) emit(sk);
    emit(length);
    emit(length);
    const auto report = dtis::interp::Verify(table.Table(), *machine);
    std::printf("job              %s, feed %.6g mm/min, path %.6g mm\n", job.name.c_str(),
                o.feed_mm_s * 60.0, length);
    std::printf("feasible start   %.6f s (planner %s)\n", start_time,
                dtis::interp::PlannerName(o.planner));
    std::printf("first solve      %.6f s, %zu periods of %.6f ms (IPOPT status %d)\n", t1,
                a.s.size() - 1, a.h_ms, static_cast<int>(a.status));
    std::printf("minimum time     %.6f s, %d periods of %.6f ms (IPOPT status %d)\n", t2, n2,
                b.h_ms, static_cast<int>(b.status));
    std::printf("verifier         worst ratio %.9f (%s)\n", report.worst_ratio,
                report.worst.c_str());
    if (!out.empty()) dtis::io::WriteSetpoints(out, table.Table());
    if (!arc_out.empty()) {
      std::string text;
      for (const double sk : b.s) text += fmt::format("{}\n", sk);
      text += fmt::format("{}\n{}\n", length, length);
      dtis::io::WriteFileAtomically(arc_out, text);
    }
    return (b.status == Ipopt::Solve_Succeeded || b.status == Ipopt::Solved_To_Acceptable_Level)
               ? 0
               : 2;
  } catch (const dtis::Error& e) {
    std::fprintf(stderr, "dtis_min_time: %s\n", e.what());
    return 1;
  }
}
