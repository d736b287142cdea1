# mosaicloc_add_module(<name> SOURCES ... [PUBLIC_DEPS ...] [PRIVATE_DEPS ...] [TESTS ...])
#
# Declares library target mosaicloc_<name> (alias mosaicloc::<name>) with public headers
# in include/mosaicloc/<name>/, our compile options, and one GoogleTest executable
# mosaicloc_<name>_test from TESTS, registered with CTest under the label "unit".

# mosaicloc_target_options(<target> [STANDARD <n>]): C++20 unless told otherwise (the
# ViSP-facing C++17 island), warnings as errors, sanitizers when MOSAICLOC_SANITIZE (address,
# undefined) or MOSAICLOC_TSAN (thread) is on.
function(mosaicloc_target_options target)
  cmake_parse_arguments(ARG "" "STANDARD" "" ${ARGN})
  if(NOT ARG_STANDARD)
    set(ARG_STANDARD 20)
  endif()
  target_compile_features(${target} PUBLIC cxx_std_${ARG_STANDARD})
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Woverloaded-virtual -Werror)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_CXX_COMPILER_VERSION VERSION_LESS 13)
    # GCC 12 at -O3 reports impossible overlaps in std::string concatenation (GCC bug 105329).
    target_compile_options(${target} PRIVATE -Wno-restrict)
  endif()
  if(MOSAICLOC_SANITIZE)
    target_compile_options(${target} PUBLIC -fsanitize=address,undefined
      -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined)
  endif()
  if(MOSAICLOC_TSAN)
    target_compile_options(${target} PUBLIC -fsanitize=thread -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=thread)
  endif()
  if(MOSAICLOC_FUZZ)
    # Coverage for the fuzzers' guidance in every library they reach.
    target_compile_options(${target} PUBLIC -fsanitize=fuzzer-no-link)
  endif()
  if(MOSAICLOC_PRECOMPILED_HEADERS AND ARG_STANDARD EQUAL 20 AND NOT target STREQUAL "mosaicloc_precompiled")
    target_precompile_headers(${target} REUSE_FROM mosaicloc_precompiled)
    # The header is compiled position-independent, as the modules' libraries are, and a
    # compiler takes it only into compilations alike (executables are otherwise -fPIE).
    target_compile_options(${target} PRIVATE -fPIC)
  endif()
endfunction()

# mosaicloc_add_precompiled_headers(): target mosaicloc_precompiled, whose precompiled header
# every C++20 target reuses (MOSAICLOC_PRECOMPILED_HEADERS). A compiler takes a precompiled
# header only into a compilation with the same code-generation options, so it is compiled
# with ours, position-independent, and holds only libraries whose headers no definition of a
# target changes (fmt's and spdlog's depend on how they were built, which only their users are
# told). The headers are those most of the sources include. A target the header does not
# suit fails to build (CMake adds -Winvalid-pch; our warnings are errors).
function(mosaicloc_add_precompiled_headers)
  add_library(mosaicloc_precompiled OBJECT ${PROJECT_SOURCE_DIR}/cmake/precompiled.cpp)
  target_link_libraries(mosaicloc_precompiled PRIVATE Eigen3::Eigen opencv_core opencv_imgproc
    nlohmann_json::nlohmann_json yaml-cpp)
  mosaicloc_target_options(mosaicloc_precompiled)
  target_compile_options(mosaicloc_precompiled PRIVATE -fPIC)
  target_precompile_headers(mosaicloc_precompiled PRIVATE
    <algorithm> <array> <chrono> <cmath> <cstdint> <cstdio> <filesystem> <fstream> <functional>
    <map> <memory> <numbers> <optional> <random> <sstream> <string> <string_view> <utility> <vector>
    <Eigen/Core> <Eigen/Geometry> <Eigen/LU> <opencv2/core.hpp> <opencv2/imgproc.hpp>
    <nlohmann/json.hpp> <yaml-cpp/yaml.h>)
endfunction()

# mosaicloc_gtest_suites(<target> LABEL <label>): registers the GoogleTest program <target>
# with CTest, one test per suite (cmake/GTestSuites.cmake lists them once it is built), named
# <short>:<Suite>, where <short> is the target's name without "mosaicloc_" and "_test".
function(mosaicloc_gtest_suites target)
  cmake_parse_arguments(ARG "" "LABEL" "" ${ARGN})
  string(REGEX REPLACE "^mosaicloc_(.*)_test$" "\\1" short ${target})
  set(listed "${CMAKE_CURRENT_BINARY_DIR}/${target}_suites.cmake")
  add_custom_command(TARGET ${target} POST_BUILD
    COMMAND ${CMAKE_COMMAND} -D TEST_EXECUTABLE=$<TARGET_FILE:${target}> -D CTEST_FILE=${listed}
      -D PREFIX=${short} -D LABEL=${ARG_LABEL} "-D ENVIRONMENT=MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA}"
      -P ${PROJECT_SOURCE_DIR}/cmake/GTestSuites.cmake
    BYPRODUCTS ${listed}
    VERBATIM)
  # CTest reads the list when it exists; before the program is built it says so.
  set(include "${CMAKE_CURRENT_BINARY_DIR}/${target}_include.cmake")
  file(WRITE ${include}
    "if(EXISTS [==[${listed}]==])\n  include([==[${listed}]==])\nelse()\n"
    "  add_test([==[${short}:NOT_BUILT]==] [==[${target}_NOT_BUILT]==])\nendif()\n")
  set_property(DIRECTORY APPEND PROPERTY TEST_INCLUDE_FILES ${include})
endfunction()

function(mosaicloc_add_module name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS;TESTS;TEST_DEPS" ${ARGN})
  set(target mosaicloc_${name})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(mosaicloc::${name} ALIAS ${target})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  mosaicloc_target_options(${target})

  if(MOSAICLOC_BUILD_TESTS AND ARG_TESTS)
    set(test_target mosaicloc_${name}_test)
    add_executable(${test_target} ${ARG_TESTS})
    target_link_libraries(${test_target} PRIVATE ${target} ${ARG_TEST_DEPS}
      mosaicloc::test_support GTest::gtest GTest::gmock GTest::gtest_main)
    mosaicloc_target_options(${test_target})
    add_dependencies(mosaicloc_unit_tests ${test_target})
    mosaicloc_gtest_suites(${test_target} LABEL unit)
  endif()
endfunction()
