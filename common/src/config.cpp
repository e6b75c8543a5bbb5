#include "hil/config.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string_view>
#include <unordered_map>

#include "hil/config_files.hpp"
#include "hil/text_file.hpp"

namespace hil::cfg {
namespace {

std::string describe(const YAML::Node& n) {
  if (!n || n.IsNull()) return "nothing";
  if (n.IsMap()) return "a mapping";
  if (n.IsSequence()) return "a list";
  return "'" + n.Scalar() + "'";
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::string join(const std::vector<std::string>& words) {
  std::string out;
  for (const auto& w : words) out += (out.empty() ? "" : ", ") + w;
  return out;
}

}  // namespace

bool parse_number(std::string_view text, double& value) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  return ec == std::errc() && ptr == text.data() + text.size() && std::isfinite(value);
}

std::string closest(std::string_view word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = word.size() / 2 + 2;  // beyond this a suggestion misleads more than helps
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) best_d = d, best = c;
  }
  return best;
}

namespace {

// yaml-cpp keeps the first of two equal keys and says nothing; a config whose author wrote a key
// twice meant one of them, so it is refused. Also bounds the walk: aliases can make a small file
// a huge tree ("billion laughs"), or a cycle (an anchor aliased inside itself: &x {c: *x}), which
// every later reader would follow forever.
constexpr int kMaxDepth = 64;
void check_tree(const YAML::Node& node, const std::string& origin, std::size_t& visited, int depth = 0) {
  if (++visited > 1'000'000) throw Error(origin + ": more than a million YAML nodes (aliases?); refused");
  if (depth > kMaxDepth) {
    const YAML::Mark at = node.Mark();
    throw Error(origin + ":" + std::to_string(at.line + 1) + ":" + std::to_string(at.column + 1) + ": nested more than " +
                std::to_string(kMaxDepth) + " levels deep (an alias inside its own anchor?); refused");
  }
  if (node.IsSequence()) {
    for (const auto& item : node) check_tree(item, origin, visited, depth + 1);
  } else if (node.IsMap()) {
    // A hash of the keys seen: comparing each key with every earlier one took 10 s for a 4 MB
    // register map of 74 000 registers (on the server's I/O thread, for GET /api/rigs).
    std::unordered_map<std::string_view, YAML::Mark> seen;
    for (const auto& kv : node) {
      if (kv.first.IsScalar()) {
        const std::string& key = kv.first.Scalar();  // the node's own text: lives as long as the tree
        const auto [first, added] = seen.emplace(key, kv.first.Mark());
        if (!added) {
          const YAML::Mark at = kv.first.Mark();
          throw Error(origin + ":" + std::to_string(at.line + 1) + ":" + std::to_string(at.column + 1) + ": duplicate key '" +
                      key + "' (first at line " + std::to_string(first->second.line + 1) + ")");
        }
      }
      check_tree(kv.first, origin, visited, depth + 1);  // a key may be a mapping too
      check_tree(kv.second, origin, visited, depth + 1);
    }
  }
}

YAML::Node checked(YAML::Node node, const std::string& origin) {
  std::size_t visited = 0;
  check_tree(node, origin, visited);
  return node;
}

}  // namespace

namespace {

thread_local ReadFiles* innermost_read_files = nullptr;

}  // namespace

FileStamp stamp_of(const std::filesystem::path& file) {
  FileStamp s;
  s.path = file;
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return s;
  s.exists = true;
  s.device = st.st_dev;
  s.inode = st.st_ino;
  s.bytes = static_cast<std::uint64_t>(st.st_size);
  s.modified_ns = st.st_mtim.tv_sec * 1'000'000'000LL + st.st_mtim.tv_nsec;
  s.changed_ns = st.st_ctim.tv_sec * 1'000'000'000LL + st.st_ctim.tv_nsec;
  return s;
}

bool unchanged(const std::vector<FileStamp>& files) {
  return std::all_of(files.begin(), files.end(), [](const FileStamp& f) { return stamp_of(f.path) == f; });
}

ReadFiles::ReadFiles() : outer_(innermost_read_files) { innermost_read_files = this; }

ReadFiles::~ReadFiles() { innermost_read_files = outer_; }

void ReadFiles::note(const std::filesystem::path& file) {
  if (innermost_read_files == nullptr) return;
  const FileStamp stamp = stamp_of(file);
  for (ReadFiles* r = innermost_read_files; r != nullptr; r = r->outer_) r->files_.push_back(stamp);
}

Node Node::load_file(const std::filesystem::path& file, std::string* text) {
  ReadFiles::note(file);  // before any refusal: a file fixed later is read again
  auto shared = std::make_shared<const std::filesystem::path>(file);
  // A config is a page or two (the largest this project ships is 2 KB); a file of megabytes is a
  // mistake or an attack, and parsing it held up its reader (a 6.7 MB register map kept the
  // server's I/O thread, aborts included, for 60 s). Refused before it is read.
  constexpr std::uintmax_t kMaxYamlBytes = 1 << 20;
  std::error_code size_error;  // none: read_text_file says why the file cannot be read
  if (const auto bytes = std::filesystem::file_size(file, size_error); !size_error && bytes > kMaxYamlBytes) {
    throw Error(file.string() + ": " + std::to_string(bytes) + " bytes, more than the " + std::to_string(kMaxYamlBytes) +
                " bytes (1 MiB) a YAML config file may have; refused");
  }
  std::string content;
  try {
    content = read_text_file(file, "a YAML file");
  } catch (const std::runtime_error& e) {
    throw Error(e.what());
  }
  try {
    Node root(checked(YAML::Load(content), file.string()), shared, "", YAML::Mark());
    if (text != nullptr) *text = std::move(content);
    return root;
  } catch (const YAML::Exception& e) {
    throw Error(file.string() + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) +
                ": YAML syntax: " + e.msg);
  }
}

Node Node::load_string(std::string_view text, const std::string& origin) {
  auto shared = std::make_shared<const std::filesystem::path>(origin);
  try {
    return Node(checked(YAML::Load(std::string(text)), origin), shared, "", YAML::Mark());
  } catch (const YAML::Exception& e) {
    throw Error(origin + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) +
                ": YAML syntax: " + e.msg);
  }
}

Node Node::child(const YAML::Node& value, std::string path, YAML::Mark mark) const {
  return Node(value, file_, std::move(path), mark);
}

void Node::fail(std::string_view message) const {
  std::string where = file_->string();
  if (mark_.line >= 0) where += ":" + std::to_string(line()) + ":" + std::to_string(column());
  throw Error(where + ": " + (path_.empty() ? std::string("(top level)") : path_) + ": " + std::string(message));
}

void Node::require(bool ok, std::string_view why) const {
  if (ok) return;
  fail(std::string(why) + ", got " + describe(node_));
}

void Node::allow_keys(std::initializer_list<std::string_view> allowed) const {
  allow_keys(std::vector<std::string>(allowed.begin(), allowed.end()));
}

void Node::allow_keys(const std::vector<std::string>& allowed) const {
  if (!node_.IsMap()) fail("expected a mapping of " + join(allowed) + ", got " + describe(node_));
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.Scalar();
    if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
    const std::string hint = closest(key, allowed);
    child(it->second, path_.empty() ? key : path_ + "." + key, it->first.Mark())
        .fail("unknown key '" + key + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") +
              "; allowed: " + join(allowed));
  }
}

bool Node::has(std::string_view key) const { return find(key).has_value(); }

std::optional<Node> Node::find(std::string_view key) const {
  if (!node_.IsMap()) fail("expected a mapping, got " + describe(node_));
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    if (it->first.Scalar() != key) continue;
    // Errors about a value point at its key: that is the line a person edits.
    return child(it->second, path_.empty() ? std::string(key) : path_ + "." + std::string(key), it->first.Mark());
  }
  return std::nullopt;
}

Node Node::at(std::string_view key) const {
  if (auto n = find(key)) return *n;
  fail("missing required key '" + std::string(key) + "'");
}

std::vector<std::pair<std::string, Node>> Node::entries() const {
  if (!node_.IsMap()) fail("expected a mapping, got " + describe(node_));
  std::vector<std::pair<std::string, Node>> out;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.Scalar();
    out.emplace_back(key, child(it->second, path_.empty() ? key : path_ + "." + key, it->first.Mark()));
  }
  return out;
}

std::vector<Node> Node::items() const {
  if (!node_.IsSequence()) fail("expected a list, got " + describe(node_));
  std::vector<Node> out;
  std::size_t i = 0;
  for (const auto& item : node_) {
    out.push_back(child(item, path_ + "[" + std::to_string(i++) + "]", item.Mark()));
  }
  return out;
}

double Node::number() const {
  if (!node_.IsScalar()) fail("expected a number, got " + describe(node_));
  const std::string& s = node_.Scalar();
  double v = 0;
  if (!parse_number(s, v)) fail("expected a number, got '" + s + "'");
  return v;
}

long long Node::integer() const {
  if (!node_.IsScalar()) fail("expected a whole number, got " + describe(node_));
  const std::string& s = node_.Scalar();
  long long v = 0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size()) fail("expected a whole number, got '" + s + "'");
  return v;
}

bool Node::boolean() const {
  if (node_.IsScalar()) {
    const std::string& s = node_.Scalar();
    if (s == "true") return true;
    if (s == "false") return false;
  }
  fail("expected true or false, got " + describe(node_));
}

std::string Node::text() const {
  if (!node_.IsScalar()) fail("expected a text value, got " + describe(node_));
  return node_.Scalar();
}

std::vector<double> Node::numbers() const {
  std::vector<double> out;
  for (const auto& item : items()) out.push_back(item.number());
  return out;
}

double Node::number(std::string_view key, double fallback) const {
  auto n = find(key);
  return n ? n->number() : fallback;
}

long long Node::integer(std::string_view key, long long fallback) const {
  auto n = find(key);
  return n ? n->integer() : fallback;
}

bool Node::boolean(std::string_view key, bool fallback) const {
  auto n = find(key);
  return n ? n->boolean() : fallback;
}

namespace {
long long integer_within(const Node& n, long long lo, long long hi, std::string_view unit, std::string_view reason) {
  const long long x = n.integer();
  n.require(x >= lo && x <= hi, "must be " + std::to_string(lo) + ".." + std::to_string(hi) + std::string(unit) +
                                    (reason.empty() ? std::string() : " (" + std::string(reason) + ")"));
  return x;
}
}  // namespace

long long Node::integer_in(std::string_view key, long long fallback, long long lo, long long hi, std::string_view reason) const {
  const auto n = find(key);
  return n ? integer_within(*n, lo, hi, "", reason) : fallback;
}

std::chrono::milliseconds Node::milliseconds_in(std::string_view key, std::chrono::milliseconds fallback, long long lo_ms,
                                                long long hi_ms, std::string_view reason) const {
  const auto n = find(key);
  return n ? std::chrono::milliseconds(integer_within(*n, lo_ms, hi_ms, " ms", reason)) : fallback;
}

std::string Node::text(std::string_view key, std::string_view fallback) const {
  auto n = find(key);
  return n ? n->text() : std::string(fallback);
}

std::filesystem::path Node::resolve_path(const std::string& relative) const {
  std::filesystem::path p(relative);
  if (p.is_absolute()) return p;
  return file_->parent_path() / p;
}

std::vector<std::string> comma_list(std::string_view text) {
  std::vector<std::string> items;
  for (std::size_t from = 0; from <= text.size();) {
    const std::size_t comma = std::min(text.find(',', from), text.size());
    if (comma > from) items.emplace_back(text.substr(from, comma - from));
    from = comma + 1;
  }
  return items;
}

const std::string* repeated(const std::vector<std::string>& items) {
  for (auto it = items.begin(); it != items.end(); ++it)
    if (std::find(items.begin(), it, *it) != it) return &*it;
  return nullptr;
}

bool plain_name(std::string_view name) {
  if (name.empty() || name.size() > 100 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '_' || ch == '-' ||
           ch == '.';
  });
}

}  // namespace hil::cfg
