# The rooms of calib/ and what each may include (calib/README.md; each room's README says the same
# in words, and tools/check_calib_rooms.cmake holds the two and every #include to it). One static
# library per room, linked only to the rooms listed here, so code that reaches across the rule does
# not link (tests/calib/CMakeLists.txt links each room alone, whole-archive).
#
# The rule that matters (ARCHITECTURE §2): the world and the estimate stay apart. The simulator (sim)
# includes core and the effects catalogue only; the estimators (ains, nlsq, legacy), the checks,
# the calibration job and the diagnosis never reach sim — the diagnosis draws its simulated runs
# through a RunSource (calib/effects/run_source.hpp) that its callers provide. Only the paper's
# tables, which drive the whole experiment, include both.
set(IMUCAL_CALIB_ROOMS core effects sim ains nlsq legacy checks input pipeline diagnosis studies/design studies/paper
    studies/fleet)
set(IMUCAL_CALIB_ESTIMATE ains nlsq legacy checks input pipeline diagnosis studies/design studies/fleet)
set(calib_room_deps_core "")
set(calib_room_deps_effects core)
set(calib_room_deps_sim core effects)
set(calib_room_deps_ains core)
set(calib_room_deps_nlsq core)
set(calib_room_deps_legacy core)
set(calib_room_deps_checks core ains)
set(calib_room_deps_input core effects checks)
set(calib_room_deps_pipeline core ains nlsq legacy checks)
set(calib_room_deps_diagnosis core effects ains nlsq legacy)
set(calib_room_deps_studies/design core ains checks diagnosis)
set(calib_room_deps_studies/paper core effects sim ains nlsq legacy checks)
set(calib_room_deps_studies/fleet core effects ains)

# calib_room_closure(ROOM OUT): every room ROOM reaches through its dependencies, itself excluded.
function(calib_room_closure room out)
  set(seen "")
  set(todo ${calib_room_deps_${room}})
  while(todo)
    list(POP_FRONT todo r)
    if(NOT r IN_LIST seen)
      list(APPEND seen ${r})
      list(APPEND todo ${calib_room_deps_${r}})
    endif()
  endwhile()
  set(${out} ${seen} PARENT_SCOPE)
endfunction()

# calib_room_rule_violations(OUT): the rule's breaches in the graph above, one line each; empty
# when it holds. A room unknown, a cycle, the estimate side reaching sim, sim reaching anything
# but core and effects, or effects reaching anything but core.
function(calib_room_rule_violations out)
  set(bad "")
  foreach(room ${IMUCAL_CALIB_ROOMS})
    foreach(d ${calib_room_deps_${room}})
      if(NOT d IN_LIST IMUCAL_CALIB_ROOMS)
        list(APPEND bad "calib/${room} depends on '${d}', which is no room of calib/")
      endif()
    endforeach()
    calib_room_closure(${room} reach)
    list(JOIN reach ", " reach_text)
    if(room IN_LIST reach)
      list(APPEND bad "calib/${room} depends on itself through ${reach_text}: the rooms must not form a cycle")
    endif()
    if(room IN_LIST IMUCAL_CALIB_ESTIMATE AND sim IN_LIST reach)
      list(APPEND bad "calib/${room} is on the estimate side and reaches the simulator (calib/sim) through ${reach_text}")
    endif()
    if(room STREQUAL sim OR room STREQUAL effects)
      list(REMOVE_ITEM reach core effects)
      list(JOIN reach ", " reach_text)
      if(reach)
        list(APPEND bad "calib/${room} reaches ${reach_text}: the simulator may include calib/core and calib/effects only, the effects catalogue calib/core only")
      endif()
    endif()
  endforeach()
  set(${out} ${bad} PARENT_SCOPE)
endfunction()
