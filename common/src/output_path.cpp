#include "hil/output_path.hpp"

#include <fstream>
#include <stdexcept>
#include <string>

namespace hil {
namespace {

constexpr std::size_t kSignatureBytes = 4096;

std::string kind_of(std::filesystem::file_type t) {
  using T = std::filesystem::file_type;
  switch (t) {
    case T::block: return "a block device";
    case T::character: return "a character device";
    case T::fifo: return "a FIFO";
    case T::socket: return "a socket";
    default: return "not a regular file";
  }
}

// The file's first bytes hold `signature`; false for an empty file too (the caller lets it go).
bool holds_signature(const std::filesystem::path& file, std::string_view signature, bool& empty) {
  std::ifstream in(file, std::ios::binary);
  std::string head(kSignatureBytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  empty = head.empty();
  return head.find(signature) != std::string::npos;
}

}  // namespace

void check_output_file(std::string_view option, const std::filesystem::path& target,
                       const std::vector<std::filesystem::path>& inputs, std::string_view what, std::string_view signature) {
  const std::string named = std::string(option) + " " + target.string();
  std::error_code ec;
  const auto status = std::filesystem::symlink_status(target, ec);
  if (ec || status.type() == std::filesystem::file_type::not_found) return;  // a new file
  using T = std::filesystem::file_type;
  if (std::filesystem::is_directory(target, ec))
    throw std::invalid_argument(named + ": is a folder; give " + std::string(what) + "'s file name");
  for (const auto& input : inputs) {
    // equivalent() is false with an error when either does not exist: a new file is no input.
    if (std::filesystem::equivalent(target, input, ec)) {
      throw std::invalid_argument(named + ": is the input " + input.string() +
                                  ", which it would overwrite; give another file name");
    }
  }
  if (status.type() == T::symlink) {
    std::error_code link_ec;
    const auto to = std::filesystem::read_symlink(target, link_ec);
    throw std::invalid_argument(named + ": is a symbolic link" + (link_ec ? "" : " to " + to.string()) +
                                "; the tool neither writes through a link nor replaces it: give the file itself or a new name");
  }
  if (status.type() != T::regular) {
    throw std::invalid_argument(named + ": is " + kind_of(status.type()) + ", which " + std::string(what) +
                                " would replace with a regular file; give a file name");
  }
  bool empty = false;
  if (!signature.empty() && !holds_signature(target, signature, empty) && !empty) {
    throw std::invalid_argument(named + ": is a file the tool did not write as " + std::string(what) + " (no '" +
                                std::string(signature) + "' in its first 4 KiB), which it would replace; give another file name");
  }
}

}  // namespace hil
