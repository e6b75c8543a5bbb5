// The operator console (GET /): one offline HTML page with its CSS, its script and dygraphs
// inlined, assembled at configure time (bench/CMakeLists.txt) from the files beside this one.
#pragma once

#include <string_view>

namespace hil::bench::console {
extern const std::string_view kPage;
}  // namespace hil::bench::console
