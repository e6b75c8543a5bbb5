// The config reader must name file, line and key for every kind of mistake a person makes.
#include "hil/config.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "temp_file.hpp"

using hil::cfg::Error;
using hil::cfg::Node;

namespace {

std::string error_of(const std::string& yaml, auto&& use) {
  try {
    use(Node::load_string(yaml, "plant.yaml"));
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(Config, UnknownKeyNamesFileLineKeyAndSuggestion) {
  const std::string msg = error_of("gas:\n  cstar_m_s: 900\n  presure_exponent: 0.35\n", [](const Node& n) {
    n.at("gas").allow_keys({"cstar_m_s", "pressure_exponent"});
  });
  EXPECT_NE(msg.find("plant.yaml:3:3"), std::string::npos) << msg;
  EXPECT_NE(msg.find("gas.presure_exponent"), std::string::npos) << msg;
  EXPECT_NE(msg.find("did you mean 'pressure_exponent'"), std::string::npos) << msg;
}

TEST(Config, WrongTypeNamesTheValue) {
  const std::string msg = error_of("a:\n  b: 1.5x\n", [](const Node& n) { (void)n.at("a").number("b"); });
  EXPECT_NE(msg.find("plant.yaml:2:3: a.b: expected a number, got '1.5x'"), std::string::npos) << msg;
}

TEST(Config, MissingKeyNamesTheMapping) {
  const std::string msg = error_of("a:\n  b: 1\n", [](const Node& n) { (void)n.at("a").number("c"); });
  EXPECT_NE(msg.find("plant.yaml:1:1: a: missing required key 'c'"), std::string::npos) << msg;
}

TEST(Config, RequireReportsTheOffendingValue) {
  const std::string msg = error_of("n: 1.2\n", [](const Node& n) {
    const Node v = n.at("n");
    v.require(v.number() < 1, "must be < 1");
  });
  EXPECT_NE(msg.find("plant.yaml:1:1: n: must be < 1, got '1.2'"), std::string::npos) << msg;
}

// The one ranged integer read the drivers use: the range (and its unit and reason) in the
// message at file:line:key, a number checked before anyone narrows it, the fallback when absent.
TEST(Config, IntegerInRangeNamesTheRangeAndTheReason) {
  const Node n = Node::load_string("link:\n  bits: 9\n  huge: 4294967298\n  wait_ms: 0\n  ok: 7\n", "link.yaml");
  const Node link = n.at("link");
  EXPECT_EQ(link.integer_in("ok", 8, 5, 8), 7);
  EXPECT_EQ(link.integer_in("absent", 8, 5, 8), 8);
  EXPECT_EQ(link.milliseconds_in("absent_ms", std::chrono::milliseconds(250), 1, 1000), std::chrono::milliseconds(250));
  const auto msg = [&](auto&& read) { return error_of("", [&](const Node&) { read(); }); };
  EXPECT_EQ(msg([&] { (void)link.integer_in("bits", 8, 5, 8, "libmodbus makes any other 8"); }),
            "link.yaml:2:3: link.bits: must be 5..8 (libmodbus makes any other 8), got '9'");
  // 4294967298 is 2 once cast to 32 bits: it must fail as the number written.
  EXPECT_EQ(msg([&] { (void)link.integer_in("huge", 1, 1, 4); }), "link.yaml:3:3: link.huge: must be 1..4, got '4294967298'");
  EXPECT_EQ(msg([&] { (void)link.milliseconds_in("wait_ms", std::chrono::milliseconds(1), 1, 600000); }),
            "link.yaml:4:3: link.wait_ms: must be 1..600000 ms, got '0'");
  EXPECT_EQ(msg([&] { (void)link.integer_in("ok", 1, 1, 8); }), "no error");
}

TEST(Config, SyntaxErrorHasLineAndColumn) {
  const std::string msg = error_of("a: [1, 2\nb: 3\n", [](const Node&) {});
  EXPECT_NE(msg.find("plant.yaml:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("YAML syntax"), std::string::npos) << msg;
}

TEST(Config, StrictScalars) {
  const Node n = Node::load_string("x: +2.5\ny: 1e3\nz: yes\nw: .nan\nk: 3\n", "t");
  EXPECT_DOUBLE_EQ(n.number("x"), 2.5);
  EXPECT_DOUBLE_EQ(n.number("y"), 1000.0);
  EXPECT_THROW((void)n.at("z").boolean(), Error);
  EXPECT_THROW((void)n.number("w"), Error);
  EXPECT_EQ(n.at("k").integer(), 3);
  EXPECT_DOUBLE_EQ(n.number("missing", 7.0), 7.0);
}

TEST(Config, ListItemsCarryTheirIndex) {
  const std::string msg = error_of("runs:\n  - a: 1\n  - a: oops\n", [](const Node& n) {
    for (const Node& r : n.at("runs").items()) (void)r.number("a");
  });
  EXPECT_NE(msg.find("runs[1].a"), std::string::npos) << msg;
  EXPECT_NE(msg.find(":3:"), std::string::npos) << msg;
}

// A folder opens as a stream on Linux; it must be refused by name before yaml-cpp reads it (which
// leaked its half-built document, as LeakSanitizer showed), and so must a missing file.
TEST(Config, FolderOrMissingFileIsRefusedNamingIt) {
  hil::test::TempDir dir;
  try {
    (void)Node::load_file(dir.path());
    FAIL() << "a folder loaded";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(dir.path().string() + ": is a folder, not a YAML file"), std::string::npos) << msg;
  }
  try {
    (void)Node::load_file(dir.path() / "missing.yaml");
    FAIL() << "a missing file loaded";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("missing.yaml: cannot open the file"), std::string::npos) << msg;
  }
  EXPECT_THROW((void)Node::load_file("/dev/null/x.yaml"), Error);
}

}  // namespace

// An alias inside its own anchor makes a cycle that every reader would follow forever (found by
// the config fuzz target as a stack overflow): refused with its place.
TEST(Config, RecursiveAliasIsRefused) {
  try {
    (void)hil::cfg::Node::load_string("a: 1\nb: &x {c: *x}\n", "cycle.yaml");
    FAIL() << "accepted";
  } catch (const hil::cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find("cycle.yaml:2:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("levels deep"), std::string::npos) << e.what();
  }
  // Deep but finite nesting within the limit still loads.
  std::string deep = "v: ";
  for (int i = 0; i < 30; ++i) deep += "[";
  for (int i = 0; i < 30; ++i) deep += "]";
  EXPECT_NO_THROW((void)hil::cfg::Node::load_string(deep, "deep.yaml"));
}

// One reading of a comma-separated list of names (--runs, --candidates, ?runs=): empty items are
// no names, so "" and "," name none, which the callers refuse as no choice.
TEST(Config, CommaListsDropEmptyItemsAndARepeatIsFound) {
  using V = std::vector<std::string>;
  EXPECT_EQ(hil::cfg::comma_list("none,adaptive"), (V{"none", "adaptive"}));
  EXPECT_EQ(hil::cfg::comma_list("a,,b,"), (V{"a", "b"}));
  EXPECT_EQ(hil::cfg::comma_list(",a"), (V{"a"}));
  EXPECT_TRUE(hil::cfg::comma_list("").empty());
  EXPECT_TRUE(hil::cfg::comma_list(",").empty());
  EXPECT_EQ(hil::cfg::repeated(V{"a", "b"}), nullptr);
  const V twice{"a", "b", "c", "b", "a"};
  ASSERT_NE(hil::cfg::repeated(twice), nullptr);
  EXPECT_EQ(*hil::cfg::repeated(twice), "b");  // the first item that repeats an earlier one
  EXPECT_EQ(hil::cfg::repeated(twice), &twice[3]);
}
