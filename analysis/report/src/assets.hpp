// report.js and report.css, embedded at build time from the files beside this one.
#pragma once

#include <string_view>

namespace hil::report::detail {
extern const std::string_view kReportJs;
extern const std::string_view kReportCss;
}  // namespace hil::report::detail
