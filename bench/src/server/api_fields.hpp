// The fields a route takes, as data: each body field and query option of a route is a FieldSpec
// (name, type, unit, range), and one validator reads a request against its route's specs. An
// unknown name is refused naming it with a "did you mean", a wrong type naming the field, a value
// outside its range naming the range and its unit; the messages come from the spec, so every
// route says them the same way. Ranges that belong to the run (a gap, a fault's size) are the
// runner's (check_injection in runner.hpp), not repeated here.
#pragma once

#include <initializer_list>
#include <limits>
#include <string>
#include <vector>

#include "api_reply.hpp"

namespace hil::bench::api {

enum class FieldType {
  text,       // a JSON string (or a query option's text)
  number,     // a finite JSON number; in the query, the whole text is the number
  whole,      // a whole number (in the query: of bytes, an offset)
  flag,       // a JSON boolean
  text_list,  // a JSON array of strings
};

struct FieldSpec {
  std::string name;
  FieldType type = FieldType::text;
  std::string unit = "";  // as said in a range's message ("rows per second", "bytes"); empty: none
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
  bool min_open = false;  // the range excludes `min` ((0, 5000])
  std::string summary = "";
};

using FieldSpecs = std::vector<FieldSpec>;

// A request's JSON body: its size is bounded by the parser (--max-body-kb), its nesting here
// before it is parsed, and a key given twice is refused naming it (request_guard.hpp). An empty
// body is an empty object.
json parse_json_body(const Request& req);

// `name` (a body field or a query option) when it is not one of `allowed`: 400 `error`, with a
// "did you mean" and `after` in the detail. `shown` is the name as it may be echoed.
void refuse_unknown(const std::string& name, const std::string& shown, const std::vector<std::string>& allowed, const char* error,
                    const std::string& after = "");

// A JSON body read against its specs: every name in it must be one of them (checked at once, in
// the body's order); each field is checked against its spec when it is read, so a field that a
// request does not use (bias_kpa beside mode stuck) is not judged.
class Fields {
 public:
  Fields(json body, const FieldSpecs& specs);

  const json& body() const { return body_; }
  bool has(const std::string& name) const { return body_.contains(name); }
  bool given(const std::string& name) const { return has(name) && !body_[name].is_null(); }
  // A field that may be absent (or null): its fallback then. Of the wrong type: 400 naming it.
  std::string text(const std::string& name, const std::string& fallback) const;
  bool flag(const std::string& name, bool fallback) const;
  std::vector<std::string> text_list(const std::string& name) const;  // absent: empty
  // A number the request needs: absent, not a number or not finite is 400 naming it.
  double number(const std::string& name) const;

 private:
  const FieldSpec& spec(const std::string& name, FieldType type) const;
  json body_;
  const FieldSpecs& specs_;
};

// A query option's value against its spec (a number, or a whole number, in its range), or
// `fallback` when it is not given: the whole text is the number (cfg::parse_number), so "20abc"
// is refused rather than read as 20.
double query_number(const Target& t, const FieldSpec& spec, double fallback);

// The spec of `name` among `specs` (a programming error when it is not there).
const FieldSpec& spec_of(const FieldSpecs& specs, const std::string& name);

}  // namespace hil::bench::api
