# Included by ctest after the discovered tests (TEST_INCLUDE_FILES, tests/CMakeLists.txt): the
# tests in tests/whole_machine_tests.txt run with nothing beside them under `ctest -j2`.
file(STRINGS "${CMAKE_CURRENT_LIST_DIR}/../whole_machine_tests.txt" imucal_whole_machine_lines)
foreach(line IN LISTS imucal_whole_machine_lines)
  string(REGEX REPLACE "#.*$" "" name "${line}")
  string(STRIP "${name}" name)
  if(name)
    set_tests_properties(${name} PROPERTIES PROCESSORS 2)
  endif()
endforeach()
