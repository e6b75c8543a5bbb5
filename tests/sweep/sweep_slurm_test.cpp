// `hilbench sweep --slurm` against a stand-in sbatch that records each argument on a line of its
// own: a folder name with a space, `$(`, quotes or '%' reaches sbatch's --output and the job
// scripts as exactly one argument (the script run by sh gives it back unchanged, and runs nothing
// of it); one with a newline or a backslash is refused before anything is made; --sbatch-arg is
// read as sbatch's getopt_long reads it (abbreviations, grouped short options, separate values);
// a 60 000-digit --time or --mem is a usage error (it overflowed std::regex's stack).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "run_command.hpp"
#include "temp_file.hpp"

namespace {

namespace fs = std::filesystem;
using hil::test::hilbench;
using hil::test::run_command;
using hil::test::slurp;
using hil::test::TempDir;

std::string sq(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  for (std::size_t from = 0; from < text.size();) {
    const auto nl = std::min(text.find('\n', from), text.size());
    out.push_back(text.substr(from, nl - from));
    from = nl + 1;
  }
  return out;
}

bool has_line(const std::vector<std::string>& lines, const std::string& line) {
  return std::find(lines.begin(), lines.end(), line) != lines.end();
}

// A folder with bin/sbatch that writes each argument as one line to sbatch.log ("--" between calls).
struct FakeSlurm {
  TempDir dir;
  fs::path log = dir.path() / "sbatch.log";
  FakeSlurm() {
    dir.write("bin/sbatch", "#!/bin/sh\nfor a in \"$@\"; do printf '%s\\n' \"$a\"; done >> " + sq(log.string()) +
                                "\necho -- >> " + sq(log.string()) +
                                "\ncase \"$*\" in *--array*) echo 101;; *) echo 102;; esac\n");
    fs::permissions(dir.path() / "bin" / "sbatch", fs::perms::owner_all);
  }
  // `hilbench sweep` with these arguments, in this folder, the stand-in first on PATH.
  hil::test::CommandResult sweep(const std::string& args) const {
    return run_command("cd " + sq(dir.path().string()) + " && PATH=" + sq((dir.path() / "bin").string()) + ":\"$PATH\" " +
                       hilbench() + " sweep " + args);
  }
  std::string calls() const { return fs::exists(log) ? slurp(log) : ""; }
};

}  // namespace

TEST(SweepSlurm, AFolderNameReachesSbatchAndTheScriptsAsOneArgumentAndRunsNothing) {
  FakeSlurm slurm;
  const auto sweep = hil::test::source_path("tests/sweep/small.yaml");
  const std::string exe = fs::canonical(hilbench()).string();
  // Stands in for hilbench when the script runs: each argument it is given, one per line.
  const auto args_file = slurm.dir.path() / "args.txt";
  slurm.dir.write("bin/print-args",
                  "#!/bin/sh\nfor a in \"$@\"; do printf '%s\\n' \"$a\"; done > " + sq(args_file.string()) + "\n");
  fs::permissions(slurm.dir.path() / "bin" / "print-args", fs::perms::owner_all);
  for (const std::string name : {"with space", "dollar $(touch PWNED) `touch PWNED`", "it's \"quoted\"", "percent %A %%"}) {
    fs::remove(slurm.log);
    const auto out = slurm.dir.path() / "sweeps" / name;
    const auto r = slurm.sweep(sq(sweep.string()) + " --out " + sq(out.string()) + " --slurm --tasks 2");
    ASSERT_EQ(r.status, 0) << name << ": " << r.output;
    // --output is one argument, '%' doubled (sbatch reads %% as one '%'), the pattern after it.
    std::string escaped;
    for (char c : (out / "slurm" / "logs").string()) escaped += c == '%' ? std::string("%%") : std::string(1, c);
    const auto calls = lines_of(slurm.calls());
    EXPECT_TRUE(has_line(calls, "--output=" + escaped + "/shard-%A_%a.out")) << name << ":\n" << slurm.calls();
    EXPECT_TRUE(has_line(calls, "--error=" + escaped + "/aggregate-%j.err")) << name << ":\n" << slurm.calls();
    EXPECT_TRUE(has_line(calls, (out / "slurm" / "array.sh").string())) << name << ":\n" << slurm.calls();
    // The scripts, run by sh with the binary swapped for print-args: the folder comes back whole.
    for (const std::string script : {"array.sh", "aggregate.sh"}) {
      std::string text = slurp(out / "slurm" / script);
      const auto at = text.find(sq(exe));
      ASSERT_NE(at, std::string::npos) << text;
      text.replace(at, sq(exe).size(), sq((slurm.dir.path() / "bin" / "print-args").string()));
      slurm.dir.write("run-" + script, text);
      fs::remove(args_file);
      const auto ran = run_command("cd " + sq(slurm.dir.path().string()) + " && SLURM_ARRAY_TASK_ID=1 sh " +
                                   sq((slurm.dir.path() / ("run-" + script)).string()));
      ASSERT_EQ(ran.status, 0) << ran.output;
      const auto given = lines_of(slurp(args_file));
      ASSERT_GE(given.size(), 3u) << script << ": " << slurp(args_file);
      EXPECT_EQ(given[0], "sweep");
      EXPECT_EQ(given[1], "--out");
      EXPECT_EQ(given[2], out.string()) << script;
      if (script == "array.sh") EXPECT_TRUE(has_line(given, "1/2")) << slurp(args_file);
    }
    EXPECT_FALSE(fs::exists(slurm.dir.path() / "PWNED")) << name;
  }
}

TEST(SweepSlurm, AFolderNameThatCannotBeQuotedSafelyIsRefusedBeforeAnythingIsMade) {
  FakeSlurm slurm;
  const auto sweep = hil::test::source_path("tests/sweep/small.yaml");
  for (const auto& [name, says] : std::vector<std::pair<std::string, std::string>>{
           {"new\nline; touch PWNED", "control character"}, {"tab\there", "control character"}, {"back\\slash", "backslash"}}) {
    const auto out = slurm.dir.path() / "sweeps" / name;
    const auto r = slurm.sweep(sq(sweep.string()) + " --out " + sq(out.string()) + " --slurm --tasks 2");
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out)) << "the folder was made";
    EXPECT_EQ(slurm.calls(), "") << "sbatch was called";
  }
  EXPECT_FALSE(fs::exists(slurm.dir.path() / "PWNED"));
}

TEST(SweepSlurm, SbatchArgumentsAreReadAsGetoptLongReadsThem) {
  FakeSlurm slurm;
  const auto sweep = hil::test::source_path("tests/sweep/small.yaml");
  const auto out = slurm.dir.path() / "out";
  const std::string base = sq(sweep.string()) + " --out " + sq(out.string()) + " --slurm --tasks 2 ";
  // Unique abbreviations of the options the submission sets, a short one inside a group, one as
  // the value sbatch would take for the option before it, a bare word (sbatch's job script), "--".
  for (const auto& [args, says] : std::vector<std::pair<std::string, std::string>>{
           {"--sbatch-arg=--outp=/tmp/x", "sbatch reads '--outp' as --output"},
           {"--sbatch-arg=--arr=1-3", "sbatch reads '--arr' as --array"},
           {"--sbatch-arg=--dep=afterok:1", "sbatch reads '--dep' as --dependency"},
           {"--sbatch-arg=--wra=id", "sbatch reads '--wra' as --wrap"},
           {"--sbatch-arg=--ch=/tmp", "sbatch reads '--ch' as --chdir"},
           {"--sbatch-arg=--open=append", "sbatch reads '--open' as --open-mode"},
           {"--sbatch-arg=--job=x", "sbatch reads '--job' as --job-name"},
           {"--sbatch-arg=--inp=/dev/null", "sbatch reads '--inp' as --input"},
           {"--sbatch-arg=--output", "--output is set by hilbench sweep --slurm itself"},
           {"--sbatch-arg=-vo/tmp/x", "-o is set by hilbench sweep --slurm itself"},
           {"--sbatch-arg=-Qe/tmp/x", "sbatch reads '-e' as --error"},
           {"--sbatch-arg=-QvJname", "sbatch reads '-J' as --job-name"},
           {"--sbatch-arg=--comment --sbatch-arg=-o/tmp/x", "sbatch reads '-o' as --output"},
           {"--sbatch-arg=--exclusive --sbatch-arg=evil.sh", "a bare word would be taken as the job script"},
           {"--sbatch-arg=-- --sbatch-arg=evil.sh", "ends sbatch's options"},
           {"--sbatch-arg=-t", "its value is missing"},
           {"--sbatch-arg=-vz", "-z is no sbatch option"}}) {
    const auto r = slurm.sweep(base + args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(says), std::string::npos) << args << ": " << r.output;
    EXPECT_EQ(slurm.calls(), "") << args;
  }
  // What sbatch takes: a value in the next argument, a group ending in an option with its value,
  // an option with an optional value, one this table does not know given with '='.
  const auto r = slurm.sweep(base +
                             "--sbatch-arg=--comment --sbatch-arg=nightly --sbatch-arg=-vt10 --sbatch-arg=--export=ALL "
                             "--sbatch-arg=--some-future-option=1");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto calls = lines_of(slurm.calls());
  for (const std::string a : {"--comment", "nightly", "-vt10", "--export=ALL", "--some-future-option=1"})
    EXPECT_TRUE(has_line(calls, a)) << a << ":\n" << slurm.calls();
}

TEST(SweepSlurm, AHugeTimeOrMemoryIsAUsageErrorNotACrash) {
  FakeSlurm slurm;
  const auto out = slurm.dir.path() / "out";
  const std::string digits(60000, '9');
  for (const auto& [option, says] :
       std::vector<std::pair<std::string, std::string>>{{"--time " + digits, "not a Slurm time limit"},
                                                        {"--mem " + digits, "not a Slurm memory size"},
                                                        {"--time 1:" + digits, "not a Slurm time limit"},
                                                        {"--account " + std::string(200, 'a'), "not a Slurm account name"}}) {
    const auto r = slurm.sweep("--out " + sq(out.string()) + " --slurm " + option);
    EXPECT_EQ(r.status, 2) << r.output.substr(0, 500);
    EXPECT_NE(r.output.find(says), std::string::npos) << r.output.substr(0, 500);
    EXPECT_LT(r.output.size(), 2000u) << "the value is shown cut";
  }
  // The forms sbatch takes still pass the check (the stand-in answers; the sweep has no plan: 1).
  for (const std::string time : {"90", "1:30", "1:30:00", "2-0", "2-12:30", "2-12:30:05", "UNLIMITED"}) {
    const auto r = slurm.sweep("--out " + sq(out.string()) + " --slurm --time " + time);
    EXPECT_EQ(r.output.find("not a Slurm time limit"), std::string::npos) << time << ": " << r.output;
  }
}
