// A file a command writes, checked before anything is read or run: the tool may create a new
// regular file or replace one it wrote, never anything else at that path. An output that is one
// of the inputs (under another spelling, ./x or a link to it) would be replaced by what is made
// of it, the input lost; a device, a FIFO or a socket would be replaced by a regular file (as
// root, /dev/full went); a symbolic link is not the file it names, and the tool does not write
// through it nor replace it; a file the tool did not write (a campaign, a report where JUnit XML
// goes) is someone's. Every option that names a file the tool writes goes through this check.
// Setup/offline code: it throws.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

namespace hil {

// Throws std::invalid_argument, naming "OPTION TARGET" and why, when the path `target` (the value
// of `option`) is a folder; the same file as one of `inputs` (by std::filesystem::equivalent, so
// links and other spellings count; an input that does not exist is no match); a symbolic link;
// anything but a regular file (a device, a FIFO, a socket); or, with a `signature`, a non-empty
// file whose first 4 KiB do not hold it (every file of this kind the tool writes does: JUnit's
// `<testsuites name="hilbench"`, a report's generator tag), so not one the tool wrote. `what`
// names the output, e.g. "the fitted model". Nothing at `target` is fine: it is made.
void check_output_file(std::string_view option, const std::filesystem::path& target,
                       const std::vector<std::filesystem::path>& inputs, std::string_view what, std::string_view signature = {});

}  // namespace hil
