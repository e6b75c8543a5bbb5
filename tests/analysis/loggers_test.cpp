// The loggers labs have (issue 49): a European CSV (';' between fields, ',' as the decimal mark, a
// byte order mark, CRLF), a file in ms, bar and rad with units in the header ("t_ms",
// "p_meas [bar]", "theta_cmd (rad)"), other column names mapped with --columns, and two
// acquisitions appended in one file (time restarting at 0). Each is the same data as a file in the
// project's own format, written from it here; each is diagnosed as that file is: the same verdict,
// the same effects, the same values (the native file's digits converted and back: within 1e-6).
// And what is ambiguous is refused naming file:line and the option to add.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "hil/analysis/measurement.hpp"
#include "hil/csv_reader.hpp"
#include "temp_file.hpp"
#include "workbench_test_util.hpp"

namespace {

namespace fs = std::filesystem;

std::vector<std::string> lines_of(const fs::path& f) {
  std::ifstream in(f);
  std::vector<std::string> out;
  for (std::string l; std::getline(in, l);) {
    if (!l.empty() && l.back() == '\r') l.pop_back();
    out.push_back(l);
  }
  return out;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string c; std::getline(ss, c, ',');) out.push_back(c);
  return out;
}

void write(const fs::path& f, const std::string& text) {
  std::ofstream out(f, std::ios::binary);
  out << text;
}

// The native file's data rows and the index of each measurement column in them.
struct Native {
  std::vector<std::string> names;
  std::vector<std::vector<std::string>> rows;
  int col(const std::string& n) const {
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == n) return static_cast<int>(i);
    return -1;
  }
};
Native read_native(const fs::path& f) {
  Native n;
  for (const auto& l : lines_of(f)) {
    if (l.empty() || l[0] == '#') continue;
    if (n.names.empty())
      n.names = split(l);
    else
      n.rows.push_back(split(l));
  }
  return n;
}

// The same file as a European logger writes it: BOM, ';' and ',' and CRLF, the metadata dropped.
fs::path european(const Native& n, const fs::path& f) {
  std::string text = "\xEF\xBB\xBF";
  auto row = [&](const std::vector<std::string>& cells) {
    std::string l;
    for (std::size_t i = 0; i < cells.size(); ++i) {
      std::string c = cells[i];
      for (char& ch : c)
        if (ch == '.') ch = ',';
      l += (i ? ";" : "") + c;
    }
    text += l + "\r\n";
  };
  row(n.names);
  for (const auto& r : n.rows) row(r);
  write(f, text);
  return f;
}

// The measurement columns in ms, bar and rad (units in the header three ways), or under other
// names (`renamed`: "time", "P1" in kPa, "cmd" in deg), the rest of the columns dropped.
fs::path other_units(const Native& n, const fs::path& f, bool renamed) {
  const int t = n.col("t_s"), c = n.col("theta_cmd_deg"), p = n.col("p_meas_mpa"), m = n.col("theta_motor_deg"),
            r = n.col("p_ref_mpa");
  std::string text = renamed ? "time,cmd,P1,enc\n" : "t_ms,theta_cmd (rad),p_meas [bar],theta_motor_rad,p_ref_bar\n";
  char b[256];
  for (const auto& row : n.rows) {
    auto v = [&](int i) { return std::stod(row[static_cast<std::size_t>(i)]); };
    if (renamed) {
      std::snprintf(b, sizeof b, "%.17g,%.17g,%.17g,%.17g\n", v(t), v(c), v(p) * 1000, v(m));
    } else {
      const double rad = std::numbers::pi / 180;
      std::snprintf(b, sizeof b, "%.17g,%.17g,%.17g,%.17g,%.17g\n", v(t) * 1000, v(c) * rad, v(p) * 10, v(m) * rad, v(r) * 10);
    }
    text += b;
  }
  write(f, text);
  return f;
}

// Two native files as one, the second's rows after the first's, its clock restarting at 0.
fs::path appended(const fs::path& a, const fs::path& b, const fs::path& f) {
  std::string text;
  bool header_seen = false;
  for (const auto& l : lines_of(a)) text += l + "\n";
  for (const auto& l : lines_of(b)) {
    if (l.empty() || l[0] == '#') continue;
    if (!header_seen) {
      header_seen = true;
      continue;
    }
    text += l + "\n";
  }
  write(f, text);
  return f;
}

nlohmann::json diagnose(const fs::path& out, const hil::analysis::DataFiles& data, const hil::CsvDialect& dialect = {}) {
  hil::analysis::DiagnoseOptions o;
  o.model_file = hil::test::nominal_model();
  o.data_files = data;
  o.out_dir = out;
  o.quiet = true;
  o.dialect = dialect;
  hil::analysis::run_diagnose(o);
  return hil::test::read_json(out / "diagnosis.json");
}

// `b` is diagnosed as `a`: verdict, effects in order, every fitted value, the fit before and after.
void expect_same_diagnosis(const nlohmann::json& a, const nlohmann::json& b, double rel) {
  EXPECT_EQ(a["verdict"], b["verdict"]);
  ASSERT_EQ(a["added"].size(), b["added"].size()) << hil::test::brief(b);
  for (std::size_t i = 0; i < a["added"].size(); ++i) {
    EXPECT_EQ(a["added"][i]["effect"], b["added"][i]["effect"]);
    for (const auto& p : a["added"][i]["parameters"]) {
      const double va = p["value"].get<double>(), vb = hil::test::param(b["added"][i], p["key"]);
      EXPECT_NEAR(vb, va, rel * std::max(1.0, std::abs(va))) << p["key"];
    }
  }
  for (const char* k : {"fit_pct", "rmse_kpa", "noise_sigma_kpa"}) {
    EXPECT_NEAR(b["before"][k].get<double>(), a["before"][k].get<double>(), rel * 100) << "before " << k;
    EXPECT_NEAR(b["after"][k].get<double>(), a["after"][k].get<double>(), rel * 100) << "after " << k;
  }
}

hil::test::Scenario run_of(const std::string& name, std::uint64_t seed) {
  hil::test::Scenario s;
  s.name = name;
  s.duration_s = 10;
  s.seed = seed;
  s.reference_yaml = hil::test::reference_square(1.0, 1.4, 1.5);
  s.truth = [](const hil::plant::Plant& p) { return hil::test::with_block(p, "valve_offset", "offset_deg: 0.7"); };
  return s;
}

std::string error_of(const fs::path& f, const hil::CsvDialect& d = {}) {
  try {
    hil::analysis::load_measurement(f, d);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Loggers, AEuropeanCsvAFileInMsAndBarAndRenamedColumnsAreDiagnosedAsTheNativeFile) {
  hil::test::TempDir dir;
  const fs::path native = hil::test::make_measurement(run_of("native", 41), dir.path());
  const Native n = read_native(native);
  const nlohmann::json want = diagnose(dir.path() / "d_native", {native});
  ASSERT_EQ(want["verdict"], "explained") << hil::test::brief(want);

  const fs::path eu = european(n, dir.path() / "european.csv");
  expect_same_diagnosis(want, diagnose(dir.path() / "d_eu", {eu}), 0);  // the same digits: the same numbers

  const fs::path units = other_units(n, dir.path() / "units.csv", false);
  expect_same_diagnosis(want, diagnose(dir.path() / "d_units", {units}), 1e-6);

  const fs::path renamed = other_units(n, dir.path() / "renamed.csv", true);
  EXPECT_NE(error_of(renamed).find("renamed.csv:1:1: missing required column 't_s'"), std::string::npos) << error_of(renamed);
  EXPECT_NE(error_of(renamed).find("--columns t_s=NAME"), std::string::npos) << error_of(renamed);
  const auto map = hil::csv_dialect("", "", "t_s=time, theta_cmd_deg=cmd, p_meas_kpa=P1, theta_motor_deg=enc");
  const nlohmann::json got = diagnose(dir.path() / "d_renamed", {renamed}, map);
  expect_same_diagnosis(want, got, 1e-6);
}

TEST(Loggers, TwoAcquisitionsAppendedInOneFileAreDiagnosedAsTwoFilesOfOneRig) {
  hil::test::TempDir dir;
  const fs::path a = hil::test::make_measurement(run_of("first", 42), dir.path());
  const fs::path b = hil::test::make_measurement(run_of("second", 43), dir.path());
  const nlohmann::json want = diagnose(dir.path() / "d_two", {a, b});
  const fs::path both = appended(a, b, dir.path() / "both.csv");
  const nlohmann::json got = diagnose(dir.path() / "d_both", {both});
  expect_same_diagnosis(want, got, 0);
  ASSERT_EQ(got["files"].size(), 2u);
  EXPECT_EQ(got["files"][1]["acquisition"], 2);
  const auto first_data = want["files"][0]["rows"].get<std::size_t>();
  EXPECT_GT(got["files"][1]["first_line"].get<std::size_t>(), first_data);
  // compare takes one acquisition and says where the second starts.
  const std::string e = error_of(both);
  EXPECT_NE(e.find("goes backwards"), std::string::npos) << e;
  EXPECT_NE(e.find("acquisition"), std::string::npos) << e;
}

TEST(Loggers, WhatIsAmbiguousIsRefusedNamingWhereAndTheOption) {
  hil::test::TempDir dir;
  const fs::path native = hil::test::make_measurement(run_of("native", 44), dir.path());
  const Native n = read_native(native);
  // Two columns of one quantity in two units.
  std::string text = "t_ms,t [s],theta_cmd_deg,p_meas_mpa\n";
  for (const auto& r : n.rows)
    text += std::to_string(std::stod(r[0]) * 1000) + "," + r[0] + "," + r[static_cast<std::size_t>(n.col("theta_cmd_deg"))] +
            "," + r[static_cast<std::size_t>(n.col("p_meas_mpa"))] + "\n";
  write(dir.path() / "two_times.csv", text);
  std::string e = error_of(dir.path() / "two_times.csv");
  EXPECT_NE(e.find("two_times.csv:1:2: columns 't_ms' and 't [s]' both read as t_s"), std::string::npos) << e;
  EXPECT_NE(e.find("--columns t_s=NAME"), std::string::npos) << e;
  EXPECT_EQ(error_of(dir.path() / "two_times.csv", hil::csv_dialect("", "", "t_ms=t_ms")), "");
  // A header that splits on two separators.
  write(dir.path() / "mixed.csv", "t_s;theta_cmd_deg,p_meas_mpa\n0;1,2\n");
  e = error_of(dir.path() / "mixed.csv");
  EXPECT_NE(e.find("mixed.csv:1:1: the header splits on both ',' and ';': name the separator (--separator"), std::string::npos)
      << e;
  // A decimal mark that changes within the file.
  std::string eu = "t_s;theta_cmd_deg;p_meas_mpa\n";
  for (int k = 0; k < 60; ++k) {
    char row[64];
    std::snprintf(row, sizeof row, "0,%03d;10;1,5\n", k + 1);
    eu += row;
  }
  eu += "0.061;10;1,5\n";
  write(dir.path() / "marks.csv", eu);
  e = error_of(dir.path() / "marks.csv");
  EXPECT_NE(e.find("marks.csv:62:1: column 't_s': not a number: '0.061'; the decimal mark is ',' as line 2 shows (name it: "
                   "--decimal '.')"),
            std::string::npos)
      << e;
  // A unit the option gives against the one the column names.
  e = error_of(native, hil::csv_dialect("", "", "p_meas_bar=p_meas_mpa"));
  EXPECT_NE(e.find("the column says mpa, the option bar"), std::string::npos) << e;
  // Options that say nothing sensible are refused before any file is read.
  EXPECT_THROW(hil::csv_dialect("|", "", ""), hil::CsvError);
  EXPECT_THROW(hil::csv_dialect("", "", "t_s"), hil::CsvError);
  EXPECT_THROW(hil::csv_dialect("", "", "t_s=a,t_ms=b"), hil::CsvError);
}
