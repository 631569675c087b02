# Small helpers shared by every target: warnings on, in one place, and the folder map checked
# (target check-layers) before the target builds.
function(fogmap_set_warnings target)
  if(TARGET check-layers)
    add_dependencies(${target} check-layers)
  endif()
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wno-deprecated-declarations)
  if(FOGMAP_WERROR)
    # GCC 12's maybe-uninitialized stays a warning: it reports the disengaged payload of a copied
    # std::optional (CloudObservation::box) as read, depending on what was inlined (the Release
    # build shows it in map_test too).
    target_compile_options(${target} PRIVATE -Werror -Wno-error=maybe-uninitialized)
  endif()
endfunction()

# Precompiled headers (FOGMAP_PCH). fogmap_add_pch(name HEADER file LIBS ...) makes the target
# `name` that precompiles `file` with the flags its LIBS give; fogmap_use_pch(target name) makes
# `target` reuse it. GCC takes a precompiled header only from identical flags (it warns,
# -Winvalid-pch, and parses the header as text where they differ), so each header is used by
# targets compiled exactly as its own: fogmap_service_pch (cmake/pch/service_headers.hpp: gRPC,
# protobuf and the generated fogmap.grpc.pb.h, Eigen, Prometheus, nlohmann/json; -pthread) by the
# services' layer, the services and their mains, the harness, the pictures of runs, the view and
# fogctl; fogmap_core_pch (cmake/pch/core_headers.hpp: Eigen) by the Eigen-based libraries under
# common/ and the cores built on them.
function(fogmap_add_pch name)
  cmake_parse_arguments(ARG "" "HEADER" "LIBS" ${ARGN})
  add_library(${name} OBJECT ${PROJECT_SOURCE_DIR}/cmake/pch/pch_anchor.cpp)
  target_link_libraries(${name} PRIVATE ${ARG_LIBS})
  target_precompile_headers(${name} PRIVATE ${ARG_HEADER})
  fogmap_set_warnings(${name})
endfunction()

function(fogmap_use_pch target name)
  if(FOGMAP_PCH)
    target_precompile_headers(${target} REUSE_FROM ${name})
  endif()
endfunction()

# fogmap_add_executable(name SOURCES ... LIBS ...)
function(fogmap_add_executable name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS})
  fogmap_set_warnings(${name})
endfunction()

# What every test translation unit is compiled with. In Release the test code itself is built at -O1:
# what it calls (the libraries and services under test) keeps -O3, and the tests compile in three
# quarters of the time. (A precompiled header shared by the test binaries saved another fifth of a
# gRPC test file's time, but GCC takes a header only with the very same flags, and the test targets
# differ: -fPIC from PCL's and Qt's interfaces, -pthread. One per target costs more than it saves.)
# Under AddressSanitizer (the dev preset) the test code is built at -O1 as well, and without ASan's
# use-after-scope checks (a poisoned stack slot for every temporary of every gtest body): on
# tracker_test.cpp that took 66 s to compile, 31 s now. The libraries and services under test keep
# the preset's -O2 and every check. The sampling oracles of ellipsoid_test.cpp run on inlined Eigen
# code, which under the sanitizers at -O1 took minutes per test: fogmap_keep_optimised keeps -O2.
function(fogmap_test_flags target)
  target_compile_definitions(${target} PRIVATE FOGMAP_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  target_compile_options(${target} PRIVATE $<$<CONFIG:Release>:-O1>)
  if(FOGMAP_SANITIZE MATCHES "address")
    target_compile_options(${target} PRIVATE -O1 -fno-sanitize-address-use-after-scope)
  endif()
endfunction()

# fogmap_keep_optimised(source...): test sources that stay at the build type's optimisation under
# the sanitizers (see fogmap_test_flags); each is then its own unit, outside the unity batches.
function(fogmap_keep_optimised)
  if(FOGMAP_SANITIZE MATCHES "address")
    set_source_files_properties(${ARGN} PROPERTIES COMPILE_OPTIONS -O2)
  endif()
endfunction()

# fogmap_add_test(name [SERIAL] [CLUSTERS gtest-filter] SOURCES ... LIBS ...): one GoogleTest binary,
# its tests discovered by ctest. SERIAL tests (whole clusters of processes) run alone, so timing is
# not starved, and carry the label "integration"; the others carry "unit" and are built by the
# target unit-tests (with the binaries they start), which the dev preset builds and runs under the
# sanitizers. CLUSTERS names the tests of a unit binary that are whole clusters of processes
# (a gtest filter, ':'-separated): they are integration tests, run alone.
function(fogmap_add_test name)
  cmake_parse_arguments(ARG "SERIAL" "CLUSTERS" "SOURCES;LIBS" ${ARGN})
  fogmap_add_executable(${name} SOURCES ${ARG_SOURCES} LIBS ${ARG_LIBS} GTest::gtest_main)
  fogmap_test_flags(${name})
  if(ARG_SERIAL)
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 120 PROPERTIES TIMEOUT 900 RUN_SERIAL TRUE LABELS integration)
  else()
    if(ARG_CLUSTERS)
      gtest_discover_tests(${name} DISCOVERY_TIMEOUT 120 TEST_FILTER "-${ARG_CLUSTERS}" PROPERTIES TIMEOUT 600 LABELS unit)
      gtest_discover_tests(${name} DISCOVERY_TIMEOUT 120 TEST_FILTER "${ARG_CLUSTERS}"
                           PROPERTIES TIMEOUT 900 RUN_SERIAL TRUE LABELS integration)
    else()
      gtest_discover_tests(${name} DISCOVERY_TIMEOUT 120 PROPERTIES TIMEOUT 600 LABELS unit)
    endif()
    set_property(GLOBAL APPEND PROPERTY FOGMAP_UNIT_TESTS ${name})
  endif()
endfunction()
