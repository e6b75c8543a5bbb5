// A JSON file the tool wrote itself (run.json, plan.json, analysis.json, jobs.json), read back as
// hostile: it may be cut short, edited by hand, or not JSON at all. Setup/offline code.
#pragma once

#include <filesystem>
#include <string_view>

#include <nlohmann/json.hpp>

namespace hil {

// The file's JSON. Throws std::runtime_error naming where: read_text_file's errors ("FILE: cannot
// open the file: REASON", "FILE: is not a regular file", ...), or "FILE:LINE:COLUMN: not JSON:
// REASON" (the parser's reason, e.g. an unexpected end of input).
nlohmann::json read_json_file(const std::filesystem::path& file);

// The same for text already read; `origin` names it in errors.
nlohmann::json parse_json_text(std::string_view text, const std::string& origin);
// "LINE:COLUMN" (1-based) of the byte a JSON parser stopped at (parse_error::byte: 1-based, past
// the end for a cut text).
std::string json_error_position(std::string_view text, std::size_t byte);

}  // namespace hil
