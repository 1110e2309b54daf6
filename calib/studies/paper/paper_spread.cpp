#include "calib/studies/paper/paper_spread.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace imucal::calib::studies::paper {

namespace {

/// Ranks 1..n, ties given their mean rank.
std::vector<double> ranks(const std::vector<double>& v) {
  std::vector<size_t> order(v.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j + 1 < order.size() && v[order[j + 1]] == v[order[i]]) ++j;
    const double mean_rank = 0.5 * static_cast<double>(i + j) + 1.0;
    for (size_t k = i; k <= j; ++k) r[order[k]] = mean_rank;
    i = j + 1;
  }
  return r;
}

double pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n;
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0.0 && syy > 0.0 ? sxy / std::sqrt(sxx * syy) : 0.0;
}

double coefficient_of_variation(const std::vector<double>& v) {
  const double n = static_cast<double>(v.size());
  const double mean = std::accumulate(v.begin(), v.end(), 0.0) / n;
  double ss = 0.0;
  for (double x : v) ss += (x - mean) * (x - mean);
  return mean != 0.0 ? std::sqrt(ss / (n - 1.0)) / mean : 0.0;
}

}  // namespace

std::vector<double> paper_column_values(const std::vector<PaperRow>& rows, size_t column,
                                        size_t metric) {
  std::vector<double> out;
  for (const PaperRow& r : rows) out.push_back(r[column][metric]);
  return out;
}

double rank_correlation(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size() || x.size() < 2)
    throw std::invalid_argument("rank correlation: needs two equally long lists of 2 or more");
  return pearson(ranks(x), ranks(y));
}

PaperSpread paper_spread(const std::vector<PaperRow>& rows) {
  if (rows.size() < 2) throw std::invalid_argument("paper spread: needs at least two units");
  PaperSpread s;
  const auto ains = static_cast<size_t>(PaperColumn::kFactoryAins);
  for (size_t c = 0; c < s.cv.size(); ++c)
    for (size_t m = 0; m < 2; ++m) {
      s.cv[c][m] = coefficient_of_variation(paper_column_values(rows, c, m));
      s.rank_with_factory_ains[c][m] =
          rank_correlation(paper_column_values(rows, ains, m), paper_column_values(rows, c, m));
    }
  s.orientation_with_acceleration =
      rank_correlation(paper_column_values(rows, ains, 0), paper_column_values(rows, ains, 1));
  return s;
}

std::vector<PaperRow> paper_published_rows() {
  const PaperPublished& p = paper_published();
  std::vector<PaperRow> rows(6);
  for (size_t u = 0; u < rows.size(); ++u)
    for (size_t c = 0; c < rows[u].size(); ++c)
      rows[u][c] = {p.orientation_mdeg[u][c], p.accel_ug[u][c]};
  return rows;
}

std::vector<PaperRow> paper_rows(const PaperTables& tables) {
  std::vector<PaperRow> rows;
  for (const PaperUnitResult& u : tables.units) {
    PaperRow r{};
    for (size_t c = 0; c < r.size(); ++c)
      r[c] = {u.metrics[c].orientation_rmse_mdeg, u.metrics[c].accel_rmse_ug};
    rows.push_back(r);
  }
  return rows;
}

}  // namespace imucal::calib::studies::paper
