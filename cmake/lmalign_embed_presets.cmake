# Writes OUT, a C++ file holding every DIR/*.yaml (the presets, configs/presets/) as
# lmalign::detail::embedded_presets(): (name, text) pairs, the name being the file's stem.
# Run by src/CMakeLists.txt at build time: cmake -DDIR=... -DOUT=... -P this file.
file(GLOB _files "${DIR}/*.yaml")
list(SORT _files)
set(_body "")
foreach(_f ${_files})
  get_filename_component(_name "${_f}" NAME_WE)
  file(READ "${_f}" _text)
  string(FIND "${_text}" ")lmalign_preset\"" _bad)
  if(NOT _bad EQUAL -1)
    message(FATAL_ERROR "${_f}: contains the raw-string delimiter )lmalign_preset\"")
  endif()
  string(APPEND _body "      {\"${_name}\", R\"lmalign_preset(${_text})lmalign_preset\"},\n")
endforeach()
set(_out "// Generated from configs/presets/*.yaml by cmake/lmalign_embed_presets.cmake: do not edit.
#include <string>
#include <utility>
#include <vector>

namespace lmalign::detail {
const std::vector<std::pair<std::string, std::string>>& embedded_presets() {
  static const std::vector<std::pair<std::string, std::string>> presets{
${_body}  };
  return presets;
}
}  // namespace lmalign::detail
")
# Only rewrite when the text changed (no needless recompilation).
if(EXISTS "${OUT}")
  file(READ "${OUT}" _old)
  if(_old STREQUAL _out)
    return()
  endif()
endif()
file(WRITE "${OUT}" "${_out}")
