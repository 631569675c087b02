# Small helpers shared by every target: warnings on, one place.
function(fogmap_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-deprecated-declarations)
endfunction()

# fogmap_add_executable(name SOURCES ... LIBS ...)
function(fogmap_add_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS})
  fogmap_set_warnings(${name})
endfunction()

# fogmap_add_test(name [SERIAL] SOURCES ... LIBS ...): one GoogleTest binary, its tests discovered
# by ctest. SERIAL tests (whole clusters of processes) run alone, so timing is not starved.
function(fogmap_add_test name)
  cmake_parse_arguments(ARG "SERIAL" "" "SOURCES;LIBS" ${ARGN})
  fogmap_add_executable(${name} SOURCES ${ARG_SOURCES} LIBS ${ARG_LIBS} GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE FOGMAP_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  if(ARG_SERIAL)
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 900 RUN_SERIAL TRUE)
  else()
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES TIMEOUT 600)
  endif()
endfunction()
