# The one palette of the project's plots (common/palette/signals.txt: a colour per signal), read
# once at configure time into
#   hil/palette.hpp (generated into HIL_PALETTE_INCLUDE_DIR): hil::palette::color("p_meas_mpa")
#   HIL_PALETTE_JS_TEXT: "window.hilPalette = Object.freeze({...});", inlined before the console's
#   and the reports' scripts.
# So a signal has the same colour in the console and in every report.
set(HIL_PALETTE_FILE ${PROJECT_SOURCE_DIR}/common/palette/signals.txt)
set_property(DIRECTORY ${PROJECT_SOURCE_DIR} APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${HIL_PALETTE_FILE})
file(STRINGS ${HIL_PALETTE_FILE} _palette_lines)
set(HIL_PALETTE_JS_TEXT "")
set(_palette_cpp "")
foreach(_line IN LISTS _palette_lines)
  if(_line MATCHES "^[ \t]*(#|$)")
    continue()
  endif()
  if(NOT _line MATCHES "^([a-z_]+)[ \t]+([#a-z0-9(),.]+)[ \t]*$")
    message(FATAL_ERROR "${HIL_PALETTE_FILE}: '${_line}' is not 'signal colour'")
  endif()
  string(APPEND HIL_PALETTE_JS_TEXT "  ${CMAKE_MATCH_1}: \"${CMAKE_MATCH_2}\",\n")
  string(APPEND _palette_cpp "    {\"${CMAKE_MATCH_1}\", \"${CMAKE_MATCH_2}\"},\n")
endforeach()
set(HIL_PALETTE_JS_TEXT "// The one palette (common/palette/signals.txt), generated at configure time.\nwindow.hilPalette = Object.freeze({\n${HIL_PALETTE_JS_TEXT}});\n")
set(HIL_PALETTE_CPP_ENTRIES "${_palette_cpp}")
configure_file(${PROJECT_SOURCE_DIR}/common/palette/palette.hpp.in ${PROJECT_BINARY_DIR}/generated/include/hil/palette.hpp @ONLY)
set(HIL_PALETTE_INCLUDE_DIR ${PROJECT_BINARY_DIR}/generated/include)
