// JSON files the tool reads back (run.json, plan.json, analysis.json): an error names the file,
// line and column where the text stops being JSON, with the parser's reason.
#include <gtest/gtest.h>

#include <fstream>

#include "hil/json_file.hpp"
#include "temp_file.hpp"

namespace {

std::string error_of(const std::string& text) {
  try {
    hil::parse_json_text(text, "f.json");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(accepted)";
}

}  // namespace

TEST(JsonFile, ErrorsNameTheLineAndColumnWhereTheTextStopsBeingJson) {
  EXPECT_EQ(hil::parse_json_text("{\"a\": [1, 2]}", "f.json")["a"][1], 2);
  // A bad literal on line 2, column 8 (the parser stops after reading "tru,").
  const std::string bad = error_of("{\n  \"a\": tru,\n  \"b\": 1\n}");
  EXPECT_EQ(bad.rfind("f.json:2:", 0), 0u) << bad;
  EXPECT_NE(bad.find(": not JSON: syntax error"), std::string::npos) << bad;
  EXPECT_NE(bad.find("invalid literal"), std::string::npos) << bad;
  // Cut short: the end of the text.
  const std::string cut = error_of("{\n  \"a\": [1,");
  EXPECT_EQ(cut.rfind("f.json:2:11: not JSON: ", 0), 0u) << cut;
  EXPECT_NE(cut.find("unexpected end of input"), std::string::npos) << cut;
  // Empty, and a number beyond double.
  EXPECT_EQ(error_of("").rfind("f.json:1:1: not JSON: ", 0), 0u) << error_of("");
  EXPECT_NE(error_of("1e400").find("f.json"), std::string::npos) << error_of("1e400");
}

TEST(JsonFile, AFileNamesItselfAndAMissingOneIsSaid) {
  hil::test::TempDir dir;
  std::ofstream(dir.path() / "cut.json") << "{\"runs\": [";
  try {
    hil::read_json_file(dir.path() / "cut.json");
    ADD_FAILURE() << "a cut file was read";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir.path() / "cut.json").string() + ":1:11: not JSON: ", 0), 0u) << e.what();
  }
  try {
    hil::read_json_file(dir.path() / "none.json");
    ADD_FAILURE() << "a missing file was read";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), (dir.path() / "none.json").string() + ": cannot open the file: No such file or directory");
  }
}
