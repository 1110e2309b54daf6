# The rooms of calib/ and what each may include (calib/README.md; each room's README says the same
# in words). Read with tools/room_graph.cmake, which holds the whole tree's rules; one static library
# per room, linked only to the rooms listed here, so code that reaches across the rule does not link
# (tests/CMakeLists.txt links each room alone, whole-archive); tools/check_rooms.cmake holds every
# #include and README to it.
#
# The rule that matters (ARCHITECTURE §2): the world and the estimate stay apart. The simulator (sim)
# includes core and the effects catalogue only; the estimators (ains, nlsq, legacy), the checks,
# the calibration job and the diagnosis never reach sim — the diagnosis draws its simulated runs
# through a RunSource (calib/effects/run_source.hpp) that its callers provide. Only the paper's
# tables, which drive the whole experiment, include both. calib/ includes nothing of ours but
# sequences/ (profile types, and the designer's generator and validator).
imucal_room(calib/core           LIBRARY imucal_calib_core           MAY_INCLUDE sequences)
imucal_room(calib/effects        LIBRARY imucal_calib_effects        MAY_INCLUDE calib/core)
imucal_room(calib/sim            LIBRARY imucal_calib_sim            MAY_INCLUDE calib/core calib/effects sequences)
imucal_room(calib/ains           LIBRARY imucal_calib_ains           MAY_INCLUDE calib/core)
imucal_room(calib/nlsq           LIBRARY imucal_calib_nlsq           MAY_INCLUDE calib/core)
imucal_room(calib/legacy         LIBRARY imucal_calib_legacy         MAY_INCLUDE calib/core)
imucal_room(calib/checks         LIBRARY imucal_calib_checks         MAY_INCLUDE calib/core calib/ains sequences)
imucal_room(calib/input          LIBRARY imucal_calib_input          MAY_INCLUDE calib/core calib/effects calib/checks)
imucal_room(calib/pipeline       LIBRARY imucal_calib_pipeline       MAY_INCLUDE calib/core calib/ains calib/nlsq calib/legacy calib/checks)
imucal_room(calib/diagnosis      LIBRARY imucal_calib_diagnosis      MAY_INCLUDE calib/core calib/effects calib/ains calib/nlsq calib/legacy)
imucal_room(calib/studies/design LIBRARY imucal_calib_studies_design MAY_INCLUDE calib/core calib/ains calib/checks calib/diagnosis sequences)
imucal_room(calib/studies/paper  LIBRARY imucal_calib_studies_paper  MAY_INCLUDE calib/core calib/effects calib/sim calib/ains calib/nlsq calib/legacy calib/checks sequences)
imucal_room(calib/studies/fleet  LIBRARY imucal_calib_studies_fleet  MAY_INCLUDE calib/core calib/effects calib/ains)

imucal_room_rule(ROOMS calib/ains calib/nlsq calib/legacy calib/checks calib/input calib/pipeline calib/diagnosis
                       calib/studies/design calib/studies/fleet
                 NEVER_REACH calib/sim
                 BECAUSE "the world and the estimate stay apart: nothing on the estimate side reaches the simulator (calib/README.md)")
imucal_room_rule(ROOMS calib/sim REACH_ONLY calib/core calib/effects sequences
                 BECAUSE "the simulator may include calib/core and calib/effects only (and sequences/' profile types)")
imucal_room_rule(ROOMS calib/effects REACH_ONLY calib/core sequences
                 BECAUSE "the effects catalogue may include calib/core only")
