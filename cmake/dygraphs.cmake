# Debian's dygraphs (libjs-dygraphs, its UMD build), the one plotting library of every page the
# project writes: the campaign and analysis reports (analysis/report) and the operator console
# (bench). Looked up here once; both embed the same two files at configure time so every page
# works offline. scripts/setup.sh installs the package.
set(HIL_DYGRAPHS_DIR /usr/share/javascript/dygraphs CACHE PATH "Debian's libjs-dygraphs")
set(HIL_DYGRAPHS_JS ${HIL_DYGRAPHS_DIR}/dygraph.min.js)
set(HIL_DYGRAPHS_CSS ${HIL_DYGRAPHS_DIR}/dygraph.min.css)
foreach(_f IN ITEMS ${HIL_DYGRAPHS_JS} ${HIL_DYGRAPHS_CSS})
  if(NOT EXISTS ${_f})
    message(FATAL_ERROR "${_f} is missing (dygraphs: apt-get install libjs-dygraphs, or run scripts/setup.sh)")
  endif()
endforeach()
set_property(DIRECTORY ${PROJECT_SOURCE_DIR} APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${HIL_DYGRAPHS_JS} ${HIL_DYGRAPHS_CSS})
# The texts to inline, read once: without the source-map comments, which point at files no page
# carries (a browser would ask the console's server or a report's folder for them).
file(READ ${HIL_DYGRAPHS_JS} HIL_DYGRAPHS_JS_TEXT)
file(READ ${HIL_DYGRAPHS_CSS} HIL_DYGRAPHS_CSS_TEXT)
string(REGEX REPLACE "//# sourceMappingURL=[^\n]*" "" HIL_DYGRAPHS_JS_TEXT "${HIL_DYGRAPHS_JS_TEXT}")
string(REGEX REPLACE "/\\*# sourceMappingURL=[^\n]*\\*/" "" HIL_DYGRAPHS_CSS_TEXT "${HIL_DYGRAPHS_CSS_TEXT}")

# A generated .cpp holding pages as raw string literals: longer than the 65 536 characters the
# standard asks every compiler to accept, which GCC and Clang both exceed without limit; Clang's
# -Wpedantic says so each build (-Woverlength-strings). The length is intended, so not that warning.
function(hil_embedded_pages_source file)
  set_source_files_properties(${file} PROPERTIES COMPILE_OPTIONS -Wno-overlength-strings)
endfunction()
