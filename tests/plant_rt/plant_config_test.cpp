// Bad plant files fail before anything runs, naming file, line and key.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "hil/config.hpp"
#include "hil/plant/plant.hpp"
#include "temp_file.hpp"

using hil::plant::Plant;

namespace {

std::string nominal_text() {
  std::ifstream in(hil::test::source_path("configs/plant/nominal.yaml"));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Replaces the first occurrence of `from` and returns the error message of loading the result.
std::string load_error(const std::string& from, const std::string& to, int* line_out = nullptr) {
  std::string text = nominal_text();
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  if (line_out) *line_out = 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
  hil::test::TempDir dir;
  const auto file = dir.write("bad.yaml", text);
  try {
    (void)Plant::load(file);
  } catch (const hil::cfg::Error& e) {
    return e.what();
  }
  return "no error";
}

void expect_located(const std::string& msg, int line, const std::string& key, const std::string& words) {
  EXPECT_NE(msg.find("bad.yaml:" + std::to_string(line) + ":"), std::string::npos) << msg;
  EXPECT_NE(msg.find(key), std::string::npos) << msg;
  EXPECT_NE(msg.find(words), std::string::npos) << msg;
}

TEST(PlantConfig, FolderIsRefusedNamingIt) {
  hil::test::TempDir dir;
  try {
    (void)Plant::load(dir.path());
    FAIL() << "a folder loaded as a plant";
  } catch (const hil::cfg::Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir.path().string() + ": is a folder"), std::string::npos) << e.what();
  }
}

TEST(PlantConfig, NominalLoads) { EXPECT_NO_THROW((void)Plant::load(hil::test::source_path("configs/plant/nominal.yaml"))); }

TEST(PlantConfig, ExponentAtOrAboveOne) {
  int line = 0;
  const auto msg = load_error("pressure_exponent: 0.35", "pressure_exponent: 1.0", &line);
  expect_located(msg, line, "effects.gas_generator.pressure_exponent", "must be in (0, 1)");
}

TEST(PlantConfig, VolumeNotPositive) {
  int line = 0;
  const auto msg = load_error("free_volume_l: 2.0", "free_volume_l: 0", &line);
  expect_located(msg, line, "effects.gas_generator.free_volume_l", "must be > 0");
}

TEST(PlantConfig, NegativeGap) {
  int line = 0;
  const auto msg = load_error("gap_deg: 1.0", "gap_deg: -0.5", &line);
  expect_located(msg, line, "effects.backlash.gap_deg", "cannot be negative");
}

TEST(PlantConfig, TypoInKeySuggestsTheRightOne) {
  int line = 0;
  const auto msg = load_error("cstar_m_s: 900", "cstr_m_s: 900", &line);
  expect_located(msg, line, "effects.gas_generator.cstr_m_s", "did you mean 'cstar_m_s'");
}

TEST(PlantConfig, WrongType) {
  int line = 0;
  const auto msg = load_error("rate_limit_deg_s: 60", "rate_limit_deg_s: fast", &line);
  expect_located(msg, line, "effects.motor_servo.rate_limit_deg_s", "expected a number, got 'fast'");
}

TEST(PlantConfig, MissingField) {
  int line = 0;
  const auto msg = load_error("    burning_area_m2: 0.01           # Ab [m^2]\n", "", &line);
  expect_located(msg, line - 4, "effects.gas_generator", "missing required key 'burning_area_m2'");
}

TEST(PlantConfig, UnknownEffect) {
  int line = 0;
  const auto msg = load_error("  pressure_sensor:", "  presure_sensor:", &line);
  expect_located(msg, line, "presure_sensor", "did you mean 'pressure_sensor'");
}

TEST(PlantConfig, ThroatMapMustRise) {
  int line = 0;
  const auto msg = load_error("area_mm2: [40, 140]", "area_mm2: [140, 40]", &line);
  expect_located(msg, line, "effects.throat_map.area_mm2", "must not fall");
}

}  // namespace
