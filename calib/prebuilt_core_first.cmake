# imucal_prebuilt_core_first(): in a tree that links the calibration core (and the independent
# simulator, tools/altsim) from the Release tree (IMUCAL_CALIB_PREBUILT_DIR: the ASan + UBSan, TSan
# and fuzz trees, tools/sanitizers.sh), every program that links them gets their objects first on
# its link line.
#
# Why: a test file or a program instantiates the same Eigen (and project header) templates as the
# core. The linker keeps one copy of each such inline function, the first it meets, and the
# program's own objects come before the libraries on the line: the core would then run the
# sanitizer tree's instrumented -O1 copies of its hottest functions instead of the Release copies it
# was compiled with. Loaded first (whole archives, before the objects), the core's copies win:
# `GradeLegacy.MemsSigmaIsHonestMonteCarlo` 7.2 s -> 5.2 s under ASan + UBSan (Release 3.1 s),
# `OutputFilter.NullRunsDoNotNameIt` 23.2 s -> 17.0 s (Release 9.5 s); issue #51,
# docs/validation/build-and-ci.md.
# The price: a call that a sanitizer-tree file makes to such a function and does not inline also
# runs the core's uninstrumented copy (the core itself is pure arithmetic, fuzzed on its own). Under
# ASan that only leaves such a call unchecked. Under TSan it is wrong: the threaded code then ran
# the core's uninstrumented copies of std::shared_ptr's reference counting, and TSan, blind to
# their synchronisation, reported races on the deletes that follow (12 reports in the cold run
# of 2026-11-30). So only the ASan + UBSan tree asks for it (IMUCAL_CALIB_PREBUILT_FIRST=ON,
# tools/sanitizers.sh asan); the TSan and fuzz trees keep the usual order.
#
# The tree's own libraries too (the rooms this tree builds: station, drivers, db, sequences, ...),
# whole, after the core. The ASan tree compiles its test programs and most of its programs
# (tools/: imucal, stationctl, stationweb) at -O0 (IMUCAL_TEST_OPTIMIZE, IMUCAL_PROGRAM_OPTIMIZE:
# a quarter of the -O1 compile time under ASan + UBSan). Loaded first, the libraries keep their -O1
# copies of what a test or program file instantiates as well; before, db_tests ran the tests' -O0
# copies (35.5 -> 42.4 s). The libFuzzer binaries load the core alone: they link the fuzzed
# sources a second time, with coverage (tests/fuzz/CMakeLists.txt), and a whole library would
# define them twice.
option(IMUCAL_CALIB_PREBUILT_FIRST "load the prebuilt calibration core first on every link line (ASan tree)" OFF)

function(imucal_prebuilt_core_first)
  if(NOT IMUCAL_CALIB_PREBUILT_DIR OR NOT IMUCAL_CALIB_PREBUILT_FIRST)
    return()
  endif()
  # Every room's archive, whole: a program that links one room links its dependencies too, and
  # the whole core (its INTERFACE target imucal_calib) brings what any room needs (Ceres, sequences).
  # The independent simulator (tools/altsim) is linked from the Release tree too, and loaded first
  # with the core.
  set(archives "")
  set(core_targets "")
  foreach(room ${IMUCAL_ROOMS})
    if(room MATCHES "^calib/" OR room STREQUAL "tools/altsim")
      set(t ${IMUCAL_ROOM_LIBRARY_${room}})
      list(APPEND core_targets ${t})
      get_target_property(archive ${t} IMPORTED_LOCATION)
      list(APPEND archives "${archive}")
    endif()
  endforeach()
  imucal_executables_under(${PROJECT_SOURCE_DIR} programs)
  foreach(program ${programs})
    # The room link checks (room_link_<room>) link one room alone to prove what it may reach.
    if(program MATCHES "^room_link_")
      continue()
    endif()
    imucal_link_closure(${program} closure)
    set(links_core OFF)
    foreach(t ${core_targets})
      if(t IN_LIST closure)
        set(links_core ON)
      endif()
    endforeach()
    set(first "")
    if(links_core)
      list(APPEND first ${archives})
    endif()
    if(NOT imucal_fuzz_coverage IN_LIST closure)
      imucal_tree_libraries("${closure}" own)
      list(APPEND first ${own})
    endif()
    if(first)
      # LINK_OPTIONS stand before the objects on the link line (CMake's link rule).
      target_link_options(${program} BEFORE PRIVATE "LINKER:--whole-archive" ${first}
                          "LINKER:--no-whole-archive")
    endif()
    if(links_core)
      target_link_libraries(${program} PRIVATE imucal_calib imucal_altsim)
      set_property(TARGET ${program} APPEND PROPERTY LINK_DEPENDS ${archives})
    endif()
  endforeach()
endfunction()

# The archives of the static libraries this tree builds among TARGETS (a list), into OUT
# ($<TARGET_FILE:...>, for a link line).
function(imucal_tree_libraries targets out)
  set(files "")
  foreach(t ${targets})
    get_target_property(type ${t} TYPE)
    get_target_property(imported ${t} IMPORTED)
    if(type STREQUAL "STATIC_LIBRARY" AND NOT imported)
      list(APPEND files "$<TARGET_FILE:${t}>")
    endif()
  endforeach()
  set(${out} ${files} PARENT_SCOPE)
endfunction()
