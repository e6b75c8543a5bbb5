#include "api_fields.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "hil/config.hpp"
#include "hil/text_file.hpp"
#include "request_guard.hpp"

namespace hil::bench::api {
namespace {

ApiError bad_field(const std::string& detail, const std::string& field) {
  return ApiError{http::status::bad_request, "bad field", detail, field};
}

// A range's bound as written in a message: 0, 5000, 0.5.
std::string bound_text(double v) {
  if (v == std::floor(v) && std::abs(v) < 1e15) return std::to_string(static_cast<long long>(v));
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

bool in_range(const FieldSpec& s, double v) {
  const bool above = s.min_open ? v > s.min : v >= s.min;
  return above && v <= s.max && (s.type != FieldType::whole || v == std::floor(v));
}

// What a value outside its spec's range is told: "'rate_hz' must be in (0, 5000] rows per second",
// "'offset' must be a whole number of bytes >= 0" (a whole number's upper bound is where a double
// stops counting bytes exactly, not said).
std::string range_text(const FieldSpec& s) {
  const std::string unit = s.unit.empty() ? "" : " " + s.unit;
  if (s.type == FieldType::whole)
    return "'" + s.name + "' must be a whole number" + (s.unit.empty() ? "" : " of " + s.unit) + " >= " + bound_text(s.min);
  return "'" + s.name + "' must be in " + (s.min_open ? "(" : "[") + bound_text(s.min) + ", " + bound_text(s.max) + "]" + unit;
}

}  // namespace

json parse_json_body(const Request& req) {
  if (req.body().empty()) return json::object();
  json j;
  try {
    j = parse_request_json(req.body());
  } catch (const JsonRefused& e) {
    throw ApiError{http::status::bad_request, e.field.empty() ? "malformed JSON" : "duplicate key", e.what(), e.field};
  }
  if (!j.is_object()) throw ApiError{http::status::bad_request, "malformed JSON", "the body must be a JSON object"};
  return j;
}

void refuse_unknown(const std::string& name, const std::string& shown, const std::vector<std::string>& allowed, const char* error,
                    const std::string& after) {
  if (std::find(allowed.begin(), allowed.end(), name) != allowed.end()) return;
  const std::string hint = cfg::closest(name, allowed);
  throw ApiError{http::status::bad_request, error,
                 "'" + shown + "'" + (hint.empty() ? "" : " (did you mean '" + hint + "'?)") + after, shown};
}

const FieldSpec& spec_of(const FieldSpecs& specs, const std::string& name) {
  for (const auto& s : specs) {
    if (s.name == name) return s;
  }
  throw std::logic_error("no field spec '" + name + "'");
}

Fields::Fields(json body, const FieldSpecs& specs) : body_(std::move(body)), specs_(specs) {
  std::vector<std::string> names;
  for (const auto& s : specs) names.push_back(s.name);
  for (const auto& item : body_.items()) refuse_unknown(item.key(), item.key(), names, "unknown field");
}

const FieldSpec& Fields::spec(const std::string& name, FieldType type) const {
  const FieldSpec& s = spec_of(specs_, name);
  if (s.type != type) throw std::logic_error("field '" + name + "' is not read as its spec's type");
  return s;
}

namespace {

template <class T>
T typed(const json& body, const std::string& key, T fallback) {
  if (!body.contains(key) || body[key].is_null()) return fallback;
  try {
    return body[key].get<T>();
  } catch (const json::exception&) {
    throw bad_field("'" + key + "' has the wrong type", key);
  }
}

}  // namespace

std::string Fields::text(const std::string& name, const std::string& fallback) const {
  spec(name, FieldType::text);
  return typed<std::string>(body_, name, fallback);
}

bool Fields::flag(const std::string& name, bool fallback) const {
  spec(name, FieldType::flag);
  return typed<bool>(body_, name, fallback);
}

std::vector<std::string> Fields::text_list(const std::string& name) const {
  spec(name, FieldType::text_list);
  return typed<std::vector<std::string>>(body_, name, {});
}

double Fields::number(const std::string& name) const {
  const FieldSpec& s = spec(name, FieldType::number);
  if (!body_.contains(name) || !body_[name].is_number()) throw bad_field("'" + name + "' must be a number", name);
  const double v = body_[name].get<double>();
  if (!std::isfinite(v)) throw bad_field("'" + name + "' must be finite", name);
  if (!in_range(s, v)) throw bad_field(range_text(s), name);
  return v;
}

double query_number(const Target& t, const FieldSpec& spec, double fallback) {
  const auto q = t.query.find(spec.name);
  if (q == t.query.end()) return fallback;
  double value = 0;
  if (!cfg::parse_number(q->second, value))
    throw bad_field("'" + spec.name + "' must be a number, got '" + printable(q->second, 40) + "'", spec.name);
  if (!in_range(spec, value)) throw bad_field(range_text(spec), spec.name);
  return value;
}

}  // namespace hil::bench::api
