#include "hil/output_path.hpp"

#include <stdexcept>
#include <string>

namespace hil {

void check_output_file(std::string_view option, const std::filesystem::path& target,
                       const std::vector<std::filesystem::path>& inputs, std::string_view what) {
  const std::string named = std::string(option) + " " + target.string();
  std::error_code ec;
  if (std::filesystem::is_directory(target, ec))
    throw std::invalid_argument(named + ": is a folder; give " + std::string(what) + "'s file name");
  for (const auto& input : inputs) {
    // equivalent() is false with an error when either does not exist: a new file is no input.
    if (std::filesystem::equivalent(target, input, ec)) {
      throw std::invalid_argument(named + ": is the input " + input.string() +
                                  ", which it would overwrite; give another file name");
    }
  }
}

}  // namespace hil
