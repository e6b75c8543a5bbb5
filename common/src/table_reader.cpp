#include "hil/table_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <optional>

#include <nlohmann/json.hpp>

namespace hil {
namespace {

// A row is a flat object; nesting deeper than this is no telemetry, and is refused before the
// parser sees it (a message of nothing but '[' would otherwise nest as deep as it is long).
constexpr int kMaxJsonDepth = 16;
bool too_deep(std::string_view text) {
  int depth = 0;
  for (const char c : text) {
    if (c == '{' || c == '[') {
      if (++depth > kMaxJsonDepth) return true;
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
  return false;
}

}  // namespace

bool is_mcap_file(const std::filesystem::path& file) {
  std::FILE* f = std::fopen(file.c_str(), "rb");
  if (f == nullptr) return false;
  char magic[8];
  const bool yes = std::fread(magic, 1, 8, f) == 8 && std::memcmp(magic, "\x89MCAP0\r\n", 8) == 0;
  std::fclose(f);
  return yes;
}

TableReader::TableReader(const std::filesystem::path& file, CsvRequest request, std::string_view topic)
    : topic_(topic), request_(std::move(request)) {
  if (!is_mcap_file(file)) {
    csv_ = std::make_unique<CsvReader>(file, request_);
    header_ = csv_->header();
    return;
  }
  mcap_ = std::make_unique<mcap::Reader>(file);
  header_.file = file;
  // Up to the first row of the topic (or the end): its channel record is known by then.
  const auto find_channel = [&]() -> std::optional<std::uint16_t> {  // 0 is a channel id like any other
    for (const auto& [id, c] : mcap_->channels())
      if (c.topic == topic_) return id;
    return std::nullopt;
  };
  while (mcap_->next(pending_)) {
    if (mcap_->channels().at(pending_.channel_id).topic == topic_) {
      has_pending_ = true;
      break;
    }
  }
  const auto found = find_channel();
  if (!found) {
    std::string have;
    for (const auto& [id, c] : mcap_->channels()) have += (have.empty() ? "" : ", ") + c.topic.substr(0, 80);
    throw mcap::McapError(file.string() + ": no channel '" + topic_ + "' (the file has: " + (have.empty() ? "none" : have) + ")");
  }
  channel_ = *found;
  const mcap::Channel& ch = mcap_->channels().at(channel_);
  if (ch.message_encoding != "json")
    throw mcap::McapError(file.string() + ": channel '" + topic_ + "': message encoding '" + ch.message_encoding.substr(0, 40) +
                          "', a table needs 'json'");
  // The columns: the properties of the channel's JSON Schema, in their order.
  const auto schema = mcap_->schemas().find(ch.schema_id);
  if (schema != mcap_->schemas().end() && schema->second.encoding == "jsonschema" && !too_deep(schema->second.data)) {
    const auto j = nlohmann::ordered_json::parse(schema->second.data, nullptr, false);
    if (j.is_object() && j.contains("properties") && j["properties"].is_object())
      for (const auto& [k, v] : j["properties"].items()) header_.names.push_back(k);
  }
  for (const auto& [k, v] : mcap_->metadata())
    if (k == "telemetry") header_.metadata = v;
  std::vector<std::string> all = request_.required;
  all.insert(all.end(), request_.optional.begin(), request_.optional.end());
  for (std::size_t c = 0; c < all.size(); ++c) {
    const auto it = std::find(header_.names.begin(), header_.names.end(), all[c]);
    field_of_.push_back(it == header_.names.end() ? -1 : static_cast<int>(it - header_.names.begin()));
    header_.present.push_back(field_of_.back() >= 0);
    header_.field.push_back(field_of_.back());
    if (c < request_.required.size() && field_of_.back() < 0) {
      std::string have;
      for (const auto& n : header_.names) have += (have.empty() ? "" : ", ") + n;
      throw mcap::McapError(file.string() + ": channel '" + topic_ + "': its schema has no column '" + all[c] +
                            "' (it has: " + (have.empty() ? "no JSON Schema properties" : have) + ")");
    }
  }
}

TableReader::~TableReader() = default;

std::uint64_t TableReader::bytes_read() const { return csv_ ? csv_->bytes_read() : mcap_->bytes_read(); }
std::uint64_t TableReader::file_bytes() const { return csv_ ? csv_->file_bytes() : mcap_->file_bytes(); }

std::string TableReader::where(std::size_t line, std::string_view column) const {
  if (csv_) {
    // The requested column's field (it may be read from a column of another name or unit).
    std::vector<std::string> all = request_.required;
    all.insert(all.end(), request_.optional.begin(), request_.optional.end());
    const auto req = std::find(all.begin(), all.end(), column);
    const auto r = static_cast<std::size_t>(req - all.begin());
    const int field = req != all.end() && r < header_.field.size() ? header_.field[r] : -1;
    const auto it = std::find(header_.names.begin(), header_.names.end(), column);
    const std::size_t col = field >= 0                  ? static_cast<std::size_t>(field) + 1
                            : it == header_.names.end() ? 1
                                                        : static_cast<std::size_t>(it - header_.names.begin()) + 1;
    return header_.file.string() + ":" + std::to_string(line) + ":" + std::to_string(col) + ": column '" + std::string(column) +
           "'";
  }
  return header_.file.string() + ": record at byte " + std::to_string(line) + " (" + topic_ + "): column '" +
         std::string(column) + "'";
}

void TableReader::fail(std::uint64_t offset, const std::string& what) const {
  throw mcap::McapError(header_.file.string() + ": record at byte " + std::to_string(offset) + " (" + topic_ + "): " + what);
}

bool TableReader::next(CsvChunk& chunk, std::size_t max_rows) {
  if (csv_) return csv_->next(chunk, max_rows);
  const std::size_t n_req = request_.required.size() + request_.optional.size();
  chunk.values.assign(n_req, {});
  chunk.lines.clear();
  std::size_t rows = 0;
  while (rows < std::max<std::size_t>(max_rows, 1)) {
    if (!has_pending_) {
      while ((has_pending_ = mcap_->next(pending_)) && pending_.channel_id != channel_) {}
      if (!has_pending_) break;
    }
    has_pending_ = false;
    const mcap::Message& m = pending_;
    if (too_deep(m.data)) fail(m.offset, "the message nests deeper than " + std::to_string(kMaxJsonDepth) + " levels");
    const auto j = nlohmann::json::parse(m.data, nullptr, false);
    if (!j.is_object()) fail(m.offset, "the message is not a JSON object");
    if (rows == 0) chunk.first_line = m.offset;
    chunk.lines.push_back(m.offset);
    for (std::size_t c = 0; c < n_req; ++c) {
      if (field_of_[c] < 0) continue;
      const std::string& name = header_.names[static_cast<std::size_t>(field_of_[c])];
      const auto it = j.find(name);
      if (it == j.end()) fail(m.offset, "column '" + name + "': missing from the message");
      if (!it->is_number()) fail(m.offset, "column '" + name + "': not a number: " + it->dump().substr(0, 40));
      const double v = it->get<double>();
      if (!std::isfinite(v)) fail(m.offset, "column '" + name + "': not a finite number");
      if (name == request_.increasing) {
        if (have_last_ && !(v > last_increasing_)) {
          char msg[160];
          std::snprintf(msg, sizeof msg, "column '%s': %s goes backwards or repeats (%.9g after %.9g)", name.c_str(),
                        name.c_str(), v, last_increasing_);
          fail(m.offset, msg);
        }
        last_increasing_ = v, have_last_ = true;
      }
      chunk.values[c].push_back(v);
    }
    ++rows;
  }
  return rows > 0;
}

}  // namespace hil
