#pragma once
// The two stochastic effects of the catalogue as diagnosis candidates (DESIGN §7-8). They have no
// deterministic signature to refit; each is estimated through the statistics it changes.
//
//  * quantisation: an accumulating output register rounds each increment with the remainder carried,
//    so its error e_k - e_{k-1} has lag-1 autocovariance -LSB²/12, where white noise (ARW, VRW) has
//    none. Over the rest samples (each rest's mean removed) the pooled lag-1 autocovariance γ1 per
//    sensor estimates LSB² = -12 γ1 with σ(γ1) ≈ γ0/√N; the likelihood ratio is the squared z of the
//    departure from the declared LSB (one-sided). The held-out gap is that statistic on held-out rests
//    before and after the fitted LSB.
//  * bias_instability: a Gauss-Markov bias (σ, τ) not in the noise model moves each segment's bias
//    away from the run's mean, correlated over |Δt| as exp(-|Δt|/τ). In the whitened segment
//    residuals this adds σ_a² G_a + σ_g² G_g to the unit covariance, G built from the bias columns
//    of each segment; σ_a, σ_g are found by restricted maximum likelihood (base parameters profiled
//    out) on a grid, τ on a grid; LR = 2 Δℓ (χ²(2), conservative at the boundary). Held-out: each
//    fold predicted by the conditional mean given the others.
#include <array>
#include <vector>

#include "calib/diagnosis.hpp"
#include "calib/gap_linearisation.hpp"
#include "calib/whiteness.hpp"

namespace imucal::calib {

CandidateResult score_quantisation(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                   int folds);

CandidateResult score_bias_instability(const GapLinearisation& lin,
                                       const std::vector<std::vector<int>>& folds,
                                       const std::vector<double>& tau_grid_s);

}  // namespace imucal::calib
