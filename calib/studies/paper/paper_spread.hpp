#pragma once
// The per-IMU spread of a paper-like table, in kind (issue #26: "the paper's per-IMU ordering of
// the spread reproduced in kind"): how much the units scatter in each column (coefficient of
// variation), whether a unit keeps its rank across the columns (Spearman's rank correlation with
// the factory AINS column), and whether a unit's orientation error follows its acceleration error
// (rank correlation of the two metrics in the factory AINS column). The same figures for the
// paper's six IMUs and for simulated units say whether a model reproduces the ordering, not only
// the means.
#include <array>
#include <vector>

#include "calib/studies/paper/paper_tables.hpp"

namespace imucal::calib::studies::paper {

/// One unit's row: [column][0 orientation mdeg, 1 acceleration µg].
using PaperRow = std::array<std::array<double, 2>, kNumPaperColumns>;

struct PaperSpread {
  /// Per column and metric: sample standard deviation over the units / their mean.
  std::array<std::array<double, 2>, kNumPaperColumns> cv{};
  /// Per column and metric: Spearman's rank correlation of the units' values with their factory
  /// AINS values (1 for that column itself).
  std::array<std::array<double, 2>, kNumPaperColumns> rank_with_factory_ains{};
  /// Spearman's rank correlation of orientation with acceleration, factory AINS column.
  double orientation_with_acceleration = 0.0;
};

/// Spearman's rank correlation (ties by their mean rank); 0 when either side is constant. Throws
/// std::invalid_argument for sizes that differ or fewer than two values.
double rank_correlation(const std::vector<double>& x, const std::vector<double>& y);

/// One column's values over the units: rows[i][column][metric].
std::vector<double> paper_column_values(const std::vector<PaperRow>& rows, size_t column,
                                        size_t metric);

/// The spread of `rows` (at least two units). Throws std::invalid_argument otherwise.
PaperSpread paper_spread(const std::vector<PaperRow>& rows);

/// The paper's six IMUs (Tables I–IV) as rows.
std::vector<PaperRow> paper_published_rows();

/// Simulated units as rows.
std::vector<PaperRow> paper_rows(const PaperTables& tables);

}  // namespace imucal::calib::studies::paper
