// Fuzz target "slurm_script": the bytes as the sweep folder's name (up to the first NUL) and the
// sweep's name (after it), written into the job scripts and sbatch's --output/--error by
// slurm_scripts and array_job_args (bench/src/cli/slurm_script.hpp). Each is refused with a
// UsageError, or the scripts must say exactly what was meant: as many lines as the template has
// (nothing of a name starts a line of its own), and the exec line read back as sh reads single
// quotes gives the folder unchanged; --output with '%%' read back as one '%' starts with it.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cli/cli.hpp"
#include "cli/slurm_script.hpp"
#include "fuzz_support.hpp"

namespace {

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "\nFINDING: %s\n", what.c_str());
  std::abort();
}

// The words of a line as sh splits them, for words that are plain or single-quoted (what
// sh_quoted writes, and the template's own words); double quotes are kept as they are.
std::vector<std::string> sh_words(const std::string& line) {
  std::vector<std::string> words;
  std::string w;
  bool in_word = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (c == '\'') {
      const auto end = line.find('\'', i + 1);
      if (end == std::string::npos) finding("an unterminated quote in: " + line);
      w += line.substr(i + 1, end - i - 1);
      i = end;
      in_word = true;
    } else if (c == '\\' && i + 1 < line.size()) {
      w += line[++i];
      in_word = true;
    } else if (c == ' ') {
      if (in_word) words.push_back(w), w.clear(), in_word = false;
    } else {
      w += c;
      in_word = true;
    }
  }
  if (in_word) words.push_back(w);
  return words;
}

void check_script(const std::string& script, const std::string& dir, std::size_t lines_expected) {
  std::size_t lines = 0;
  std::string exec_line;
  for (std::size_t from = 0; from < script.size();) {
    const auto nl = script.find('\n', from);
    if (nl == std::string::npos) finding("a script without its last newline");
    const std::string line = script.substr(from, nl - from);
    if (line.rfind("exec ", 0) == 0) exec_line = line;
    from = nl + 1;
    ++lines;
  }
  if (lines != lines_expected) finding("the script has " + std::to_string(lines) + " lines:\n" + script);
  const auto words = sh_words(exec_line);
  if (words.size() < 5 || words[1] != "/usr/bin/hilbench" || words[2] != "sweep" || words[3] != "--out" || words[4] != dir)
    finding("the exec line does not give the folder back: " + exec_line);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const auto nul = text.find('\0');
  const std::string dir = "/" + text.substr(0, nul);
  const std::string name = nul == std::string::npos ? "sweep" : text.substr(nul + 1);
  hil::fuzz::expect_clear_errors<hil::bench::UsageError>("slurm_scripts", [&] {
    const auto scripts = hil::bench::slurm_scripts("/usr/bin/hilbench", dir, name, 7);
    check_script(scripts.array, dir, 5);
    check_script(scripts.aggregate, dir, 4);
    const auto args = hil::bench::array_job_args(dir, name);
    for (const auto& a : args) {
      if (a.find('\n') != std::string::npos) finding("a newline in sbatch's argument " + a);
      if (a.rfind("--output=", 0) != 0) continue;
      std::string file;
      const std::string value = a.substr(9);
      for (std::size_t i = 0; i < value.size(); ++i) {
        if (value[i] == '%' && i + 1 < value.size() && value[i + 1] == '%') ++i;
        file += value[i];
      }
      if (file.rfind(dir, 0) != 0) finding("--output does not start with the folder: " + a);
    }
  });
  return 0;
}
