// A whole file read into memory, the one way every reader of ours does it (configs, run records,
// sweep rows, uploads). Hostile paths are refused up front instead of misread: a folder reads as
// empty on Linux, a FIFO would block the reader forever and a device like /dev/zero never ends.
// Setup/offline code: it allocates and does I/O.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace hil {

// The bytes of `file`. Throws std::runtime_error naming the file and the cause:
// "FILE: is a folder, not KIND", "FILE: is not a regular file", "FILE: cannot open the file: REASON"
// or "FILE: cannot read the file: REASON" (REASON the OS's, e.g. "No such file or directory").
// `kind` says what was expected, e.g. "a YAML file".
std::string read_text_file(const std::filesystem::path& file, std::string_view kind = "a file");

// Text from outside (a file's cell, a peer's error reply) as a message to a terminal quotes it:
// control bytes as \xNN (a NUL would cut the message, an escape sequence would drive the
// terminal), and at most `max_bytes` of it, then "...".
std::string printable(std::string_view text, std::size_t max_bytes);

}  // namespace hil
