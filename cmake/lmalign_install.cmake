# Install rules and the CMake / pkg-config package (docs/packaging.md). Included last by the
# top-level CMakeLists.txt, once every target exists.
#
#   find_package(lmalign 0.1 CONFIG REQUIRED)              -> lmalign::lmalign
#   find_package(lmalign CONFIG REQUIRED COMPONENTS vo)    -> also lmalign::vo (OpenCV + Ceres)
#   find_package(lmalign CONFIG REQUIRED COMPONENTS merge) -> also lmalign::merge (Ceres)
#   find_package(lmalign CONFIG REQUIRED COMPONENTS pcl)   -> also lmalign::pcl (the PCL drop-in)
#   pkg-config --cflags --libs lmalign
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(LMALIGN_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/lmalign"
    CACHE STRING "Where lmalignConfig.cmake is installed (relative to the prefix)")

# --- the core library and its headers
set_target_properties(lmalign PROPERTIES EXPORT_NAME lmalign)
install(TARGETS lmalign EXPORT lmalignTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# Every public header; vo/ only with the map builder, merge/ only with lmalign::merge, pcl.hpp always (header-only; the pcl
# component checks that PCL itself is there).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/lmalign DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.hpp" PATTERN "vo" EXCLUDE PATTERN "merge" EXCLUDE)
install(EXPORT lmalignTargets NAMESPACE lmalign:: FILE lmalignTargets.cmake
        DESTINATION ${LMALIGN_INSTALL_CMAKEDIR})

# --- optional components: a library target installed with its headers and its own export set,
# so that find_package(lmalign COMPONENTS <name>) can load it; sets <flag> ON when installed.
function(lmalign_install_component target export_name headers_dir export_set flag)
  set(${flag} OFF PARENT_SCOPE)
  if(NOT TARGET ${target})
    return()
  endif()
  set(${flag} ON PARENT_SCOPE)
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${export_name})
  install(TARGETS ${target} EXPORT ${export_set}
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/lmalign/${headers_dir}
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/lmalign FILES_MATCHING PATTERN "*.hpp")
  install(EXPORT ${export_set} NAMESPACE lmalign:: FILE ${export_set}.cmake
          DESTINATION ${LMALIGN_INSTALL_CMAKEDIR})
endfunction()

# The map builder (OpenCV + Ceres) and map merging (the pose graph needs Ceres).
lmalign_install_component(lmalign_vo vo vo lmalignVoTargets LMALIGN_INSTALLED_VO)
lmalign_install_component(lmalign_merge merge merge lmalignMergeTargets LMALIGN_INSTALLED_MERGE)

# --- the command-line tool (and its build-map helper, found beside it)
if(TARGET lmalign_cli)
  install(TARGETS lmalign_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  # Its plotting scripts (lmalign experiment, lmalign merge), found at <bin>/../share/lmalign/
  # scripts (apps/lmalign/cli_util.cpp, find_script).
  install(FILES ${PROJECT_SOURCE_DIR}/scripts/plot_experiment.py
                ${PROJECT_SOURCE_DIR}/scripts/plot_merge.py
          DESTINATION ${CMAKE_INSTALL_DATADIR}/lmalign/scripts)
endif()
if(TARGET lmalign_build_map_cli)
  install(TARGETS lmalign_build_map_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()

# --- the package files
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/lmalignConfig.cmake.in
  ${PROJECT_BINARY_DIR}/package/lmalignConfig.cmake
  INSTALL_DESTINATION ${LMALIGN_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/package/lmalignConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/package/lmalignConfig.cmake
              ${PROJECT_BINARY_DIR}/package/lmalignConfigVersion.cmake
              # finds PCL's parts without PCL's own config (see the file), for the pcl component
              ${PROJECT_SOURCE_DIR}/cmake/lmalign_pcl.cmake
        DESTINATION ${LMALIGN_INSTALL_CMAKEDIR})

# pkg-config: the core library only. It is static by default, so its private dependencies are
# listed for static linking (Libs.private / Requires.private).
set(LMALIGN_PC_LIBS_PRIVATE "-fopenmp")
# Relocatable: the prefix is found from the .pc file's own place (cmake --install --prefix X).
string(REGEX REPLACE "[^/]+" ".." LMALIGN_PC_UP "${CMAKE_INSTALL_LIBDIR}/pkgconfig")
configure_file(${PROJECT_SOURCE_DIR}/cmake/lmalign.pc.in ${PROJECT_BINARY_DIR}/package/lmalign.pc
               @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/package/lmalign.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
