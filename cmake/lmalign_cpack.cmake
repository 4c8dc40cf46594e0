# The Debian package (docs/packaging.md, "Debian package"): `make package`, i.e. `cpack -G DEB` in
# the build directory, packs what `make install` installs, under /usr, into
# lmalign_<version>_<arch>.deb. Included after lmalign_install.cmake.
#
# Dependencies are Debian package names: the shared libraries the CLI and the Python module load
# come from dpkg-shlibdeps (dpkg-dev); the -dev packages that lmalignConfig.cmake and lmalign.pc
# need (find_dependency, Requires) and Python's are listed below.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME lmalign)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "lmalign developers <lmalign@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "align sparse landmark maps of visual SLAM / SfM (confidence-weighted ICP)")
# (The summary is the control file's first Description line; CPack indents the rest.)
set(CPACK_PACKAGE_DESCRIPTION
    "lmalign aligns two sparse landmark maps (mini-maps) of feature-based visual
SLAM or SfM and reports the rigid transform, a trust verdict and its covariance.

This package holds the C++ library (static) and its headers, the CMake package
(find_package(lmalign)), the pkg-config file, the lmalign command-line tool,
and the Python package lmalign for Debian's python3.")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # lmalign_<version>_<arch>.deb
# Install with CMAKE_INSTALL_PREFIX=/usr (and DESTDIR into CPack's staging folder), so that the
# Python package goes where Debian's python3 looks for the prefix /usr (python/CMakeLists.txt).
set(CPACK_SET_DESTDIR ON)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)

# The CMake package's find_dependency() calls and lmalign.pc's Requires.
set(_lmalign_deb_depends "libeigen3-dev (>= 3.3)" libyaml-cpp-dev nlohmann-json3-dev)
# The Python module is built for one Python minor version.
if(TARGET _lmalign)
  set(_lmalign_py "${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR}")
  math(EXPR _lmalign_py_next "${Python3_VERSION_MINOR} + 1")
  list(APPEND _lmalign_deb_depends "python3 (>= ${_lmalign_py})"
       "python3 (<< ${Python3_VERSION_MAJOR}.${_lmalign_py_next})" python3-numpy)
  # Byte-compiled on install, and the .pyc files removed before removal (py3compile, py3clean).
  set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
      ${PROJECT_SOURCE_DIR}/cmake/deb/postinst ${PROJECT_SOURCE_DIR}/cmake/deb/prerm)
  set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
endif()
list(JOIN _lmalign_deb_depends ", " CPACK_DEBIAN_PACKAGE_DEPENDS)
# What the optional CMake components find again (find_package(lmalign COMPONENTS merge vo pcl)),
# and lmalign.merge's Dask scale-out.
set(_lmalign_deb_suggests)
if(LMALIGN_INSTALLED_MERGE OR LMALIGN_INSTALLED_VO)
  list(APPEND _lmalign_deb_suggests libceres-dev)
endif()
if(LMALIGN_INSTALLED_VO)
  list(APPEND _lmalign_deb_suggests libopencv-dev)
endif()
list(APPEND _lmalign_deb_suggests libpcl-dev)
if(TARGET _lmalign)
  list(APPEND _lmalign_deb_suggests python3-distributed)
endif()
list(JOIN _lmalign_deb_suggests ", " CPACK_DEBIAN_PACKAGE_SUGGESTS)

include(CPack)
