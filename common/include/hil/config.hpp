// The YAML reader every room uses for its configuration. Setup-time only: it allocates and
// throws. Every error message names the file, the line and column, and the key path at fault,
// e.g. "configs/plant/x.yaml:12:5: effects.gas_generator.pressure_exponent: must be < 1".
#pragma once

#include <chrono>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace hil::cfg {

// A configuration error; what() names file:line:column and the key.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Node {
 public:
  // Throws Error for a missing file or a YAML syntax error (with its line and column). `text`:
  // the file as read and parsed, for a snapshot of exactly what was loaded.
  static Node load_file(const std::filesystem::path& file, std::string* text = nullptr);
  // For configs posted over an API or built in tests; `origin` stands in for the file name.
  static Node load_string(std::string_view text, const std::string& origin);

  const std::filesystem::path& file() const { return *file_; }
  const std::string& path() const { return path_; }
  int line() const { return mark_.line + 1; }
  int column() const { return mark_.column + 1; }
  bool is_map() const { return node_.IsMap(); }
  bool is_sequence() const { return node_.IsSequence(); }
  bool is_scalar() const { return node_.IsScalar(); }
  bool is_null() const { return !node_ || node_.IsNull(); }

  // Mapping. allow_keys() rejects any key not listed, naming the closest allowed one.
  void allow_keys(std::initializer_list<std::string_view> allowed) const;
  void allow_keys(const std::vector<std::string>& allowed) const;
  bool has(std::string_view key) const;
  Node at(std::string_view key) const;  // required key
  std::optional<Node> find(std::string_view key) const;
  std::vector<std::pair<std::string, Node>> entries() const;  // in file order

  // Sequence.
  std::vector<Node> items() const;

  // Scalars, strictly typed: "1.5x" is not a number, "yes" is not a number.
  double number() const;
  long long integer() const;
  bool boolean() const;
  std::string text() const;
  std::vector<double> numbers() const;  // a sequence of numbers

  // Shorthands for required and defaulted keys of a mapping.
  double number(std::string_view key) const { return at(key).number(); }
  double number(std::string_view key, double fallback) const;
  long long integer(std::string_view key, long long fallback) const;
  bool boolean(std::string_view key, bool fallback) const;
  std::string text(std::string_view key) const { return at(key).text(); }
  std::string text(std::string_view key, std::string_view fallback) const;
  // A whole number within lo..hi (both included), or `fallback` when the key is absent. Checked
  // before the caller narrows it (a cast first made 4294967298 a 2 and passed). The error names
  // file:line:key and the range: "must be <lo>..<hi>[ (<reason>)], got '<value>'"; `reason` says
  // why the range is what it is or what a device would do outside it.
  long long integer_in(std::string_view key, long long fallback, long long lo, long long hi, std::string_view reason = "") const;
  // The same for a key in milliseconds (its name ends in _ms): the range reads "<lo>..<hi> ms".
  std::chrono::milliseconds milliseconds_in(std::string_view key, std::chrono::milliseconds fallback, long long lo_ms,
                                            long long hi_ms, std::string_view reason = "") const;

  // Range checks that name this node: fail unless `ok`, with "<why>, got <value>".
  void require(bool ok, std::string_view why) const;
  // A path in this file, relative to the file's folder unless absolute.
  std::filesystem::path resolve_path(const std::string& relative) const;

  [[noreturn]] void fail(std::string_view message) const;

 private:
  Node(YAML::Node node, std::shared_ptr<const std::filesystem::path> file, std::string path, YAML::Mark mark)
      : node_(std::move(node)), file_(std::move(file)), path_(std::move(path)), mark_(mark) {}
  Node child(const YAML::Node& value, std::string path, YAML::Mark mark) const;

  YAML::Node node_;
  std::shared_ptr<const std::filesystem::path> file_;
  std::string path_;
  YAML::Mark mark_;
};

// A name that may become a file or folder name: 1-100 of [A-Za-z0-9_.-], not starting with '.'
// (so never ".", "..", or a hidden name). Campaign and run names, run ids, file names in requests.
bool plain_name(std::string_view name);

// A YAML scalar's text as a finite number: what from_chars reads, with YAML's optional leading
// '+' (`+1.0`), the whole text, and never inf or nan. False when it is none.
bool parse_number(std::string_view text, double& value);

// "did you mean" helper, also used for sub-command and effect names.
std::string closest(std::string_view word, const std::vector<std::string>& candidates);

// The items of a comma-separated list of names ("a,b", an option's or a query's value), empty
// ones dropped: "a,,b," is a and b, "" and "," are none.
std::vector<std::string> comma_list(std::string_view text);
// The first item that a later one repeats (a name given twice is a mistake), or nullptr.
const std::string* repeated(const std::vector<std::string>& items);

}  // namespace hil::cfg
