# The rooms of calib/ and what each may include (calib/README.md; each room's README says the same
# in words, and tools/check_calib_rooms.cmake holds the two and every #include to it). One static
# library per room, linked only to the rooms listed here, so code that reaches across the rule does
# not link (tests/calib/CMakeLists.txt links each room alone, whole-archive).
#
# The rule that matters: the world and the estimate stay apart. The simulator (sim) includes no
# estimator and nothing that uses one; no estimator (ains, nlsq, legacy) includes the simulator.
set(IMUCAL_CALIB_ROOMS core sim ains nlsq legacy checks pipeline diagnosis paper)
set(IMUCAL_CALIB_ESTIMATORS ains nlsq legacy)
set(calib_room_deps_core "")
set(calib_room_deps_sim core)
set(calib_room_deps_ains core)
set(calib_room_deps_nlsq core)
set(calib_room_deps_legacy core)
set(calib_room_deps_checks core ains)
set(calib_room_deps_pipeline core ains nlsq legacy checks)
set(calib_room_deps_diagnosis core sim nlsq)
set(calib_room_deps_paper core sim ains nlsq legacy checks)

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
# when it holds. A room unknown, a cycle, an estimator reaching sim, or sim reaching anything
# but core.
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
    if(room IN_LIST IMUCAL_CALIB_ESTIMATORS AND sim IN_LIST reach)
      list(APPEND bad "calib/${room} is an estimator and reaches the simulator (calib/sim) through ${reach_text}")
    endif()
    if(room STREQUAL sim)
      list(REMOVE_ITEM reach core)
      list(JOIN reach ", " reach_text)
      if(reach)
        list(APPEND bad "calib/sim, the simulator, reaches ${reach_text}: it may include calib/core only")
      endif()
    endif()
  endforeach()
  set(${out} ${bad} PARENT_SCOPE)
endfunction()
