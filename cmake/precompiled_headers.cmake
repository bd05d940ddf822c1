# Precompiled headers: about half of a typical incise file's compile time is parsing the same
# C++ standard library and Eigen headers (engine.cpp, 600 lines, preprocesses to 145k lines of
# code: 80k of the standard library, 47k of Eigen), and GoogleTest in every test file. Each
# kind of target reuses one precompiled header, built once with that kind's flags: libraries
# (position-independent), executables, test executables. A target whose flags differ (the
# Python module, third-party sources) keeps parsing its headers itself.
#
# incise_precompiled_headers(TARGET KIND): KIND is library, executable or test.

set(incise_pch_common
    <algorithm> <array> <chrono> <cmath> <cstddef> <cstdint> <cstring> <filesystem> <fstream>
    <functional> <limits> <map> <memory> <numeric> <optional> <random> <span> <sstream>
    <string> <string_view> <unordered_map> <utility> <vector>
    <Eigen/Dense> <Eigen/SparseCore>)

function(incise_pch_producer kind)
  set(producer incise_pch_${kind})
  if(TARGET ${producer})
    return()
  endif()
  set(anchor ${PROJECT_BINARY_DIR}/incise_pch_anchor.cpp)
  if(NOT EXISTS ${anchor})
    file(WRITE ${anchor} "// Compiled only to build the shared precompiled headers.\n")
  endif()
  add_library(${producer} OBJECT ${anchor})
  target_link_libraries(${producer} PRIVATE incise_options Eigen3::Eigen)
  set(headers ${incise_pch_common})
  if(kind STREQUAL "library")
    set_target_properties(${producer} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  elseif(kind STREQUAL "test")
    target_link_libraries(${producer} PRIVATE GTest::gtest)
    list(APPEND headers <gtest/gtest.h>)
  endif()
  target_precompile_headers(${producer} PRIVATE ${headers})
endfunction()

function(incise_precompiled_headers target kind)
  if(NOT INCISE_PRECOMPILE_HEADERS)
    return()
  endif()
  incise_pch_producer(${kind})
  target_precompile_headers(${target} REUSE_FROM incise_pch_${kind})
endfunction()

# g++ 12's flow-sensitive string warnings misfire on libstdc++'s own std::string code once
# inlining changes (GCC bugs 105329, 105651: std::string operator+ and find at -O2), and
# reading the standard headers from a precompiled header changes g++'s inlining choices:
# four files of ours start to fail on code that is correct. g++ 13 fixed these; clang keeps
# its own array-bounds checks in CI.
if(INCISE_PRECOMPILE_HEADERS AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU"
   AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
  target_compile_options(incise_options INTERFACE
    "$<BUILD_INTERFACE:-Wno-array-bounds;-Wno-stringop-overread;-Wno-stringop-overflow>")
endif()
