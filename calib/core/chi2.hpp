#pragma once
// χ² distribution tail, for the diagnosis' significance tests (likelihood ratios, NIS, overall
// gap): P(X > x) for X ~ χ²(k) = Q(k/2, x/2), the regularised upper incomplete gamma function, by
// its series (x < a + 1) or its continued fraction (modified Lentz), both to ~1e-15 relative.
namespace imucal::calib::core {

/// Q(a, x) = Γ(a, x) / Γ(a), a > 0, x >= 0.
double regularized_gamma_q(double a, double x);
/// P(χ²(k) > x); 1 for x <= 0.
double chi2_survival(double x, double k);
/// The x with P(χ²(k) > x) = p (bisection on chi2_survival), 0 < p < 1.
double chi2_quantile_upper(double p, double k);

}  // namespace imucal::calib::core
