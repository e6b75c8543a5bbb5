// A file a command writes, checked against what the command reads before anything is read: an
// output that is one of the inputs (under another spelling, ./x or a link to it) would be
// replaced by what is made of it, the input lost. Setup/offline code: it throws.
#pragma once

#include <filesystem>
#include <string_view>
#include <vector>

namespace hil {

// Throws std::invalid_argument when `target` (the value of `option`) is a folder: "OPTION TARGET:
// is a folder; give WHAT's file name"; or when it is the same file as one of `inputs` (by
// std::filesystem::equivalent, so links and other spellings count): "OPTION TARGET: is the input
// INPUT, which it would overwrite; give another file name". An input that does not exist is not
// a match. `what` names the output, e.g. "the fitted model".
void check_output_file(std::string_view option, const std::filesystem::path& target,
                       const std::vector<std::filesystem::path>& inputs, std::string_view what);

}  // namespace hil
