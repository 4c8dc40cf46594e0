# lmalign_library(NAME ALIAS SOURCES...): one of the project's libraries (lmalign, lmalign_merge,
# lmalign_vo): its alias (lmalign::...), the public include/ directory (the build tree's, and
# the installed prefix's), the project's warnings and position-independent code (the Python
# module links them). Each caller adds its own links and definitions.
function(lmalign_library name alias)
  add_library(${name} ${ARGN})
  add_library(${alias} ALIAS ${name})
  target_include_directories(${name} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:include>)
  target_compile_options(${name} PRIVATE -Wall -Wextra -Wpedantic)
  set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
endfunction()
