# The folder map, enforced: every quoted #include in a folder's sources must name a file of a folder
# that folder may use (cmake/layers.cmake holds the map; docs/design.md explains it).
#   cmake -DSOURCE_DIR=<repo> [-DSTAMP=<file>] -P cmake/check_layers.cmake
# Fails naming each forbidden include (file, line, the folder it reaches); on success touches STAMP.
# The build runs it (target check-layers, a dependency of every fogmap library), and so does ctest
# (repo.layers).
cmake_minimum_required(VERSION 3.25)
if(NOT SOURCE_DIR)
  message(FATAL_ERROR "check_layers.cmake: pass -DSOURCE_DIR=<the repository>")
endif()
include(${CMAKE_CURRENT_LIST_DIR}/layers.cmake)

# The folder (a key of the map) a repository-relative path belongs to: the longest key it starts with.
function(fogmap_folder_of path out)
  set(best "")
  foreach(folder IN LISTS FOGMAP_FOLDERS)
    string(LENGTH "${folder}/" length)
    string(SUBSTRING "${path}" 0 ${length} head)
    if(head STREQUAL "${folder}/")
      string(LENGTH "${best}" best_length)
      if(length GREATER best_length)
        set(best "${folder}")
      endif()
    endif()
  endforeach()
  set(${out} "${best}" PARENT_SCOPE)
endfunction()

set(violations "")
set(checked 0)
foreach(folder IN LISTS FOGMAP_FOLDERS)
  file(GLOB_RECURSE sources RELATIVE "${SOURCE_DIR}" "${SOURCE_DIR}/${folder}/*.cpp" "${SOURCE_DIR}/${folder}/*.hpp")
  foreach(source IN LISTS sources)
    fogmap_folder_of("${source}" owner)
    if(NOT owner STREQUAL folder)
      continue()  # a subfolder with its own entry
    endif()
    math(EXPR checked "${checked} + 1")
    file(STRINGS "${SOURCE_DIR}/${source}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*\"")
    foreach(line IN LISTS lines)
      string(REGEX REPLACE "^[ \t]*#[ \t]*include[ \t]*\"([^\"]+)\".*$" "\\1" included "${line}")
      if(included MATCHES "^fogmap/v1/")
        set(target protos)  # generated from protos/fogmap/v1
      else()
        fogmap_folder_of("${included}" target)
      endif()
      if(target STREQUAL "" OR target STREQUAL folder)
        continue()  # same folder, or not one of ours (a relative include)
      endif()
      if(NOT target IN_LIST FOGMAP_MAY_USE_${folder})
        string(APPEND violations "  ${source}: #include \"${included}\": ${folder} may not use ${target}\n")
      endif()
    endforeach()
  endforeach()
endforeach()

if(violations)
  message(FATAL_ERROR "The folder map (cmake/layers.cmake) forbids these includes:\n${violations}")
endif()
if(STAMP)
  file(TOUCH "${STAMP}")
endif()
message(STATUS "check_layers: ${checked} files follow the folder map")
