#pragma once
// The unit of the field-run tests (land, sea: no table): the default navigation-grade unit with no
// table misalignment, which has no meaning without a table.
#include "calib/sim/truth_sim.hpp"

namespace imucal::test_support {

inline calib::effects::UnitModel field_unit() {
  calib::effects::UnitModel u = calib::effects::default_unit();
  u.params.table_misalignment_rad.setZero();
  return u;
}

}  // namespace imucal::test_support
