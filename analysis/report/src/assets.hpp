// The page's plotting library (Debian's dygraphs), report.js and report.css, embedded at build
// time from the files beside this one and from HIL_DYGRAPHS_DIR (cmake/dygraphs.cmake).
#pragma once

#include <string_view>

namespace hil::report::detail {
extern const std::string_view kDygraphJs;
extern const std::string_view kDygraphCss;
extern const std::string_view kReportJs;
extern const std::string_view kReportCss;
}  // namespace hil::report::detail
