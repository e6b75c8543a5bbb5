// The options that name a lab logger's CSV dialect (compare and diagnose read measurements the
// same way): --separator, --decimal, --columns; each detected or not needed when left out
// (hil/csv_reader.hpp CsvDialect).
#pragma once

#include <memory>
#include <string>

#include "cli.hpp"
#include "hil/csv_reader.hpp"

namespace hil::bench {

struct CsvFormatArgs {
  std::string separator, decimal, columns;
  CsvDialect dialect() const { return csv_dialect(separator, decimal, columns); }
};

inline void add_csv_format_options(CLI::App& cmd, CsvFormatArgs& a) {
  cmd.add_option("--separator", a.separator, "the CSV's field separator (default: read off the header)")
      ->type_name("',' | ';' | tab");
  cmd.add_option("--decimal", a.decimal, "the CSV's decimal mark (default: read off the cells)")->type_name("'.' | ','");
  cmd.add_option("--columns", a.columns,
                 "columns of other names or units: t_s=time,p_meas_bar=P1 (the left side a column of the format, its "
                 "unit suffix free: _s _ms _deg _rad _mpa _kpa _bar _psi)")
      ->type_name("COL=NAME,...");
}

}  // namespace hil::bench
