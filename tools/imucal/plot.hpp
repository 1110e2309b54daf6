#pragma once
// A one-page SVG picture of a calibration for the people who would rather look than read:
// (1) the cross-check — every parameter's AINS−NLSQ difference in units of the combined σ, with
//     the ±k bound; (2) each rest period's acceleration error (eq. 53–54) for both methods;
// (3) each rest period's orientation residual (eq. 51–52). No plotting library: plain SVG.
#include <string>

#include "calib/pipeline/calibration_pipeline.hpp"

namespace imucal::tools::imucal {

/// SVG text for a pipeline result (works with one method too: then panel 1 shows err/σ against the
/// truth if `truth` is given, else is omitted).
std::string calibration_svg(const calib::pipeline::PipelineResult& r,
                            const calib::core::ParamSet* truth, double k_sigma,
                            const std::string& title);

}  // namespace imucal::tools::imucal
