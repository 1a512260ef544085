#include "dtis/geometry/bspline_surface.hpp"

#include <TColStd_Array1OfReal.hxx>
#include <TColStd_Array2OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <algorithm>
#include <cmath>
#include <limits>

#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {
namespace {

// The values at x of the polynomial sum_k c[k * stride] x^k (k = 0..degree) and of its first two
// derivatives: Horner with derivatives.
template <typename T>
void Horner2(const T* c, int stride, int degree, double x, T* f, T* f1, T* f2) {
  T b0 = c[degree * stride], b1 = T::Zero(), b2 = T::Zero();
  for (int k = degree - 1; k >= 0; --k) {
    b2 = b2 * x + b1;
    b1 = b1 * x + b0;
    b0 = b0 * x + c[k * stride];
  }
  *f = b0;
  *f1 = b1;
  *f2 = 2.0 * b2;
}

template <typename T>
void Horner1(const T* c, int degree, double x, T* f, T* f1) {
  T b0 = c[degree], b1 = T::Zero();
  for (int k = degree - 1; k >= 0; --k) {
    b1 = b1 * x + b0;
    b0 = b0 * x + c[k];
  }
  *f = b0;
  *f1 = b1;
}

template <typename T>
T Horner0(const T* c, int stride, int degree, double x) {
  T b0 = c[degree * stride];
  for (int k = degree - 1; k >= 0; --k) b0 = b0 * x + c[k * stride];
  return b0;
}

}  // namespace

std::optional<BSplineSurfaceSpans> BSplineSurfaceSpans::From(const Geom_BSplineSurface& s) {
  if (s.IsUPeriodic() || s.IsVPeriodic()) return std::nullopt;
  if (s.UDegree() > kMaxCurveDegree || s.VDegree() > kMaxCurveDegree) return std::nullopt;
  BSplineSurfaceSpans r;
  r.p_ = s.UDegree();
  r.q_ = s.VDegree();
  r.nu_ = s.NbUPoles();
  r.nv_ = s.NbVPoles();
  r.rational_ = s.IsURational() || s.IsVRational();
  TColStd_Array1OfReal uk(1, r.nu_ + r.p_ + 1), vk(1, r.nv_ + r.q_ + 1);
  s.UKnotSequence(uk);
  s.VKnotSequence(vk);
  r.uknots_.assign(uk.begin(), uk.end());
  r.vknots_.assign(vk.begin(), vk.end());
  const TColgp_Array2OfPnt& poles = s.Poles();
  const TColStd_Array2OfReal* weights = s.Weights();
  r.poles_.resize(static_cast<std::size_t>(r.nu_ * r.nv_));
  for (int i = 0; i < r.nu_; ++i) {
    for (int j = 0; j < r.nv_; ++j) {
      const gp_Pnt& pt = poles(poles.LowerRow() + i, poles.LowerCol() + j);
      const double w = r.rational_ && weights
                           ? (*weights)(weights->LowerRow() + i, weights->LowerCol() + j)
                           : 1.0;
      r.poles_[static_cast<std::size_t>(i * r.nv_ + j)] = {w * pt.X(), w * pt.Y(), w * pt.Z(), w};
    }
  }
  r.coef_.resize(static_cast<std::size_t>((r.p_ + 1) * (r.q_ + 1)));
  r.scratch_.resize(r.coef_.size());
  return r;
}

void BSplineSurfaceSpans::Cover(double u, double v) {
  if (!(u >= ulo_ && u < uhi_ && v >= vlo_ && v < vhi_)) Load(u, v);
}

void BSplineSurfaceSpans::Load(double u, double v) {
  const int su = KnotSpan(uknots_, p_, u), sv = KnotSpan(vknots_, q_, v);
  const auto knot = [](const std::vector<double>& k, int i) {
    return k[static_cast<std::size_t>(i)];
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  ulo_ = su == p_ ? -kInf : knot(uknots_, su);
  uhi_ = su == nu_ - 1 ? kInf : knot(uknots_, su + 1);
  vlo_ = sv == q_ ? -kInf : knot(vknots_, sv);
  vhi_ = sv == nv_ - 1 ? kInf : knot(vknots_, sv + 1);
  uc_ = 0.5 * (knot(uknots_, su) + knot(uknots_, su + 1));
  vc_ = 0.5 * (knot(vknots_, sv) + knot(vknots_, sv + 1));
  BasisTable du, dv;
  BasisDerivativesInSpan(uknots_, su, uc_, p_, p_, du);
  BasisDerivativesInSpan(vknots_, sv, vc_, q_, q_, dv);
  // Along u first: t[k][j] = sum_i du[k][i] P(su - p + i, sv - q + j), then along v.
  std::vector<Eigen::Vector4d>& t = scratch_;
  for (int k = 0; k <= p_; ++k) {
    for (int j = 0; j <= q_; ++j) {
      Eigen::Vector4d sum = Eigen::Vector4d::Zero();
      for (int i = 0; i <= p_; ++i) {
        sum += du[k][i] * poles_[static_cast<std::size_t>((su - p_ + i) * nv_ + sv - q_ + j)];
      }
      t[static_cast<std::size_t>(k * (q_ + 1) + j)] = sum;
    }
  }
  double fk = 1.0;
  for (int k = 0; k <= p_; ++k) {
    if (k > 0) fk *= k;
    double fl = 1.0;
    for (int l = 0; l <= q_; ++l) {
      if (l > 0) fl *= l;
      Eigen::Vector4d sum = Eigen::Vector4d::Zero();
      for (int j = 0; j <= q_; ++j) sum += dv[l][j] * t[static_cast<std::size_t>(k * (q_ + 1) + j)];
      coef_[static_cast<std::size_t>(k * (q_ + 1) + l)] = sum / (fk * fl);
    }
  }
}

void BSplineSurfaceSpans::D2(double u, double v, SurfaceDerivatives* d) {
  Cover(u, v);
  const double x = u - uc_, y = v - vc_;
  // Along u, for each power of v: A_l, dA_l/du, d2A_l/du2.
  constexpr int kMax = kMaxCurveDegree + 1;
  Eigen::Vector4d a[kMax], au[kMax], auu[kMax];
  for (int l = 0; l <= q_; ++l)
    Horner2(&coef_[static_cast<std::size_t>(l)], q_ + 1, p_, x, &a[l], &au[l], &auu[l]);
  // Then along v.
  Eigen::Vector4d s, sv, svv, su, suv;
  Horner2(a, 1, q_, y, &s, &sv, &svv);
  Horner1(au, q_, y, &su, &suv);
  const Eigen::Vector4d suu = Horner0(auu, 1, q_, y);
  if (!rational_) {
    d->p = s.head<3>();
    d->su = su.head<3>();
    d->sv = sv.head<3>();
    d->suu = suu.head<3>();
    d->suv = suv.head<3>();
    d->svv = svv.head<3>();
    return;
  }
  // The quotient S = A / w and its derivatives (The NURBS Book, A4.4 to order 2).
  const double w = s.w();
  d->p = s.head<3>() / w;
  d->su = (su.head<3>() - su.w() * d->p) / w;
  d->sv = (sv.head<3>() - sv.w() * d->p) / w;
  d->suu = (suu.head<3>() - 2.0 * su.w() * d->su - suu.w() * d->p) / w;
  d->svv = (svv.head<3>() - 2.0 * sv.w() * d->sv - svv.w() * d->p) / w;
  d->suv = (suv.head<3>() - su.w() * d->sv - sv.w() * d->su - suv.w() * d->p) / w;
}

Eigen::Vector3d BSplineSurfaceSpans::Point(double u, double v) {
  Cover(u, v);
  const double x = u - uc_, y = v - vc_;
  const auto along_u = [&](int l) {
    return Horner0(&coef_[static_cast<std::size_t>(l)], q_ + 1, p_, x);
  };
  Eigen::Vector4d s = along_u(q_);
  for (int l = q_ - 1; l >= 0; --l) s = s * y + along_u(l);
  return rational_ ? Eigen::Vector3d(s.head<3>() / s.w()) : Eigen::Vector3d(s.head<3>());
}

}  // namespace dtis::geometry
