# Finds the parts of PCL that lmalign's optional PCL code needs (include/lmalign/pcl.hpp, its
# tests, the PCL benchmark): headers, and the registration/search/kdtree/common libraries.
# Sets LMALIGN_HAVE_PCL, LMALIGN_PCL_VERSION and the imported target lmalign::pcl_peer.
#
# PCL's own CMake config (find_package(PCL)) also searches VTK, which in Debian bookworm fails
# hard with a C++-only project (VTK::mpi wants MPI::MPI_C), so we look for the files directly.
set(LMALIGN_HAVE_PCL OFF)
find_path(LMALIGN_PCL_INCLUDE_DIR NAMES pcl/registration/icp.h
          PATH_SUFFIXES pcl-1.15 pcl-1.14 pcl-1.13 pcl-1.12)
find_path(LMALIGN_FLANN_INCLUDE_DIR NAMES flann/flann.hpp)
set(_lmalign_pcl_libs)
foreach(_part registration search kdtree common)
  find_library(LMALIGN_PCL_${_part}_LIBRARY NAMES pcl_${_part})
  list(APPEND _lmalign_pcl_libs ${LMALIGN_PCL_${_part}_LIBRARY})
endforeach()
find_library(LMALIGN_FLANN_LIBRARY NAMES flann_cpp)
if(LMALIGN_PCL_INCLUDE_DIR AND LMALIGN_FLANN_INCLUDE_DIR AND LMALIGN_FLANN_LIBRARY
   AND LMALIGN_PCL_registration_LIBRARY AND LMALIGN_PCL_search_LIBRARY
   AND LMALIGN_PCL_kdtree_LIBRARY AND LMALIGN_PCL_common_LIBRARY
   AND EXISTS "${LMALIGN_PCL_INCLUDE_DIR}/pcl/pcl_config.h")
  file(STRINGS "${LMALIGN_PCL_INCLUDE_DIR}/pcl/pcl_config.h" _pcl_ver
       REGEX "^#define PCL_VERSION_PRETTY ")
  string(REGEX REPLACE ".*\"([0-9.]+)\".*" "\\1" LMALIGN_PCL_VERSION "${_pcl_ver}")
  if(LMALIGN_PCL_VERSION VERSION_GREATER_EQUAL 1.12)
    set(LMALIGN_HAVE_PCL ON)
    add_library(lmalign::pcl_peer INTERFACE IMPORTED)
    set_target_properties(lmalign::pcl_peer PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${LMALIGN_PCL_INCLUDE_DIR};${LMALIGN_FLANN_INCLUDE_DIR}"
      INTERFACE_SYSTEM_INCLUDE_DIRECTORIES "${LMALIGN_PCL_INCLUDE_DIR};${LMALIGN_FLANN_INCLUDE_DIR}"
      INTERFACE_LINK_LIBRARIES "${_lmalign_pcl_libs};${LMALIGN_FLANN_LIBRARY};Eigen3::Eigen")
  endif()
endif()
if(LMALIGN_HAVE_PCL)
  message(STATUS "lmalign: PCL ${LMALIGN_PCL_VERSION} found: building the PCL drop-in tests")
else()
  message(STATUS "lmalign: PCL (>= 1.12) not found: the PCL drop-in tests and benchmark are off")
endif()
