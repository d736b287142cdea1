# Finds every third-party dependency. Each comes from a Debian 12 package; a missing one
# stops configure naming the package to install (scripts/install-deps.sh installs them all).

function(mosaicloc_require_package name debian_package)
  find_package(${name} ${ARGN} QUIET)
  if(NOT ${name}_FOUND)
    message(FATAL_ERROR
      "mosaicloc needs ${name}: install the Debian package '${debian_package}' "
      "(sudo apt-get install ${debian_package}), or run scripts/install-deps.sh")
  endif()
endfunction()

function(mosaicloc_require_pkgconfig module debian_package target)
  pkg_check_modules(${target} QUIET IMPORTED_TARGET GLOBAL ${module})
  if(NOT ${target}_FOUND)
    message(FATAL_ERROR
      "mosaicloc needs ${module}: install the Debian package '${debian_package}' "
      "(sudo apt-get install ${debian_package}), or run scripts/install-deps.sh")
  endif()
endfunction()

find_package(PkgConfig QUIET)
if(NOT PkgConfig_FOUND)
  message(FATAL_ERROR "mosaicloc needs pkg-config: install the Debian package 'pkg-config'")
endif()

mosaicloc_require_package(Eigen3 libeigen3-dev 3.4 NO_MODULE)
mosaicloc_require_package(yaml-cpp libyaml-cpp-dev)
mosaicloc_require_package(spdlog libspdlog-dev)
mosaicloc_require_package(CLI11 libcli11-dev)
mosaicloc_require_package(nlohmann_json nlohmann-json3-dev 3.10)
mosaicloc_require_package(OpenCV libopencv-dev 4.5 COMPONENTS core imgproc imgcodecs calib3d video features2d flann)
mosaicloc_require_package(Ceres libceres-dev 2.1)
# CHOLMOD (SuiteSparse, which Ceres solves with too): the supernodal sparse Cholesky factorization.
find_path(MOSAICLOC_CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(MOSAICLOC_CHOLMOD_LIBRARY cholmod)
if(NOT MOSAICLOC_CHOLMOD_INCLUDE_DIR OR NOT MOSAICLOC_CHOLMOD_LIBRARY)
  message(FATAL_ERROR
    "mosaicloc needs CHOLMOD: install the Debian package 'libsuitesparse-dev' "
    "(sudo apt-get install libsuitesparse-dev), or run scripts/install-deps.sh")
endif()
add_library(mosaicloc_cholmod INTERFACE)
target_include_directories(mosaicloc_cholmod SYSTEM INTERFACE ${MOSAICLOC_CHOLMOD_INCLUDE_DIR})
target_link_libraries(mosaicloc_cholmod INTERFACE ${MOSAICLOC_CHOLMOD_LIBRARY})
add_library(mosaicloc::cholmod ALIAS mosaicloc_cholmod)
mosaicloc_require_pkgconfig(sqlite3 libsqlite3-dev MOSAICLOC_SQLITE3)
mosaicloc_require_package(ZLIB zlib1g-dev)
mosaicloc_require_package(PNG libpng-dev)
# Recorded frames' PNGs are inflated with libdeflate (dataset/frame_png.hpp).
mosaicloc_require_pkgconfig(libdeflate libdeflate-dev MOSAICLOC_DEFLATE)
mosaicloc_require_pkgconfig(libmodbus libmodbus-dev MOSAICLOC_MODBUS)
mosaicloc_require_pkgconfig(libv4l2 libv4l-dev MOSAICLOC_V4L2)
mosaicloc_require_pkgconfig(cpp-httplib libcpp-httplib-dev MOSAICLOC_HTTPLIB)
if(MOSAICLOC_BUILD_TESTS)
  mosaicloc_require_package(GTest libgtest-dev)
endif()
if(MOSAICLOC_BUILD_BENCHMARKS)
  mosaicloc_require_package(benchmark libbenchmark-dev)
endif()

# ViSP's package config sets CMAKE_CXX_STANDARD=17 and appends -fopenmp to CMAKE_CXX_FLAGS.
# Inside a function those are local variables and vanish on return; only the imported
# targets (directory-scoped) and the include list we hand back survive.
function(mosaicloc_find_visp)
  find_package(VISP 3.5 QUIET COMPONENTS visp_core visp_tt visp_vision)
  if(NOT VISP_FOUND)
    message(FATAL_ERROR
      "mosaicloc needs ViSP 3.5: install the Debian package 'libvisp-dev' "
      "(sudo apt-get install libvisp-dev), or run scripts/install-deps.sh")
  endif()
  set(MOSAICLOC_VISP_INCLUDE_DIRS "${VISP_INCLUDE_DIRS}" PARENT_SCOPE)
endfunction()
mosaicloc_find_visp()
add_library(mosaicloc_visp INTERFACE)
target_include_directories(mosaicloc_visp SYSTEM INTERFACE ${MOSAICLOC_VISP_INCLUDE_DIRS})
target_link_libraries(mosaicloc_visp INTERFACE visp_core visp_tt visp_vision)
add_library(mosaicloc::visp ALIAS mosaicloc_visp)
