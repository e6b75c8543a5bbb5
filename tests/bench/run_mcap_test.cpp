// telemetry.mcap, the MCAP file the recorder writes beside telemetry.csv:
//  - the real `hilbench serve` records a run; `hilbench compare --data RUN/telemetry.mcap` gives
//    the fit it gives on RUN/telemetry.csv (every number of compare.json), and `hilbench report`
//    of the run folder without its CSV prints the same table as with it;
//  - the file's bytes against the spec (magic at both ends, header first, footer's offsets and
//    CRC, the summary's records), and its channels' schemas equal the live Foxglove stream's;
//  - hostile files: a value out of range, a damaged chunk, a message that is no JSON object, a
//    missing column are refused naming the record's byte offset; a file cut inside a chunk reads
//    up to its last whole chunk.
// The independent reader (@mcap/core) is tests/mcap.
#include <gtest/gtest.h>

#include <fstream>

#include "hil/analysis/measurement.hpp"
#include "hil/mcap.hpp"
#include "hil/table_reader.hpp"
#include "hil/telemetry_schema.hpp"
#include "server/foxglove.hpp"
#include "server_process.hpp"

using namespace std::chrono_literals;
using hil::test::ServerProcess;
using nlohmann::json;

namespace {

std::string slurp_bytes(const std::filesystem::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
std::uint64_t le64(const std::string& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
  return v;
}
std::uint32_t le32(const std::string& b, std::size_t at) {
  return static_cast<std::uint32_t>(le64(b.substr(at, 4) + std::string(4, '\0'), 0));
}

// Runs hilbench with args; the exit code and what it printed.
std::pair<int, std::string> hilbench(const std::filesystem::path& dir, std::vector<std::string> args) {
  static int n = 0;
  const auto log = dir / ("cli_" + std::to_string(++n) + ".log");
  args.insert(args.begin(), hil::test::hilbench_exe());
  const auto rc = hil::test::wait_exit(hil::test::spawn(args, log), 180s);
  return {rc.value_or(-1000), hil::test::slurp(log)};
}

// A short run of paper_adaptive's kind, recorded by the real server; its folder.
std::filesystem::path record_run(const ServerProcess& server) {
  const auto api = server.client();
  const auto started =
      api.post("/api/start", {{"campaign_yaml", hil::test::short_campaign_yaml(4.0)}, {"runs", {"adaptive"}}, {"speed", 4}});
  if (started.status != 202) throw std::runtime_error("start: " + started.body);
  const json s = hil::test::wait_status(
      api, [](const json& x) { return x["state"] == "idle" && x["last"].is_object(); }, 120s);
  if (s["last"]["outcome"] != "completed") throw std::runtime_error("the run did not complete: " + s.dump());
  return server.runs_dir() / api.get("/api/runs").json()["runs"][0]["id"].get<std::string>();
}

// A small telemetry file of our own: `rows` rows of a pressure square wave, p_meas_mpa at row
// `bad_row` set to `bad_p`. Written with the writer the recorder uses, chunks of ~`chunk` bytes.
std::filesystem::path make_mcap(const std::filesystem::path& file, std::size_t rows, std::size_t bad_row = SIZE_MAX,
                                const std::string& bad_p = "500.0",
                                hil::mcap::Compression compression = hil::mcap::Compression::zstd) {
  hil::mcap::Writer w(file, "", 4096, compression);
  const auto schema = w.add_schema("hilbench/telemetry", "jsonschema",
                                   R"({"type":"object","properties":{"t_s":{},"theta_cmd_deg":{},"p_meas_mpa":{}}})");
  const auto ch = w.add_channel(schema, hil::telemetry::kTopic, "json");
  for (std::size_t i = 0; i < rows; ++i) {
    const std::string p = i == bad_row ? bad_p : ((i / 100) % 2 ? "1.500000" : "1.000000");
    w.message(ch, i * 1000000, R"({"t_s":)" + std::to_string(i * 1e-3) + R"(,"theta_cmd_deg":5.0,"p_meas_mpa":)" + p + "}");
  }
  w.close();
  return file;
}

// The byte offset of message k of a file, as the reader reports it.
std::uint64_t offset_of_message(const std::filesystem::path& file, std::size_t k) {
  hil::mcap::Reader r(file);
  hil::mcap::Message m;
  for (std::size_t i = 0; r.next(m); ++i)
    if (i == k) return m.offset;
  return 0;
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RunMcap, CompareAndReportReadTheRunsMcapAsTheyReadItsCsv) {
  ServerProcess server;
  const auto run = record_run(server);
  ASSERT_TRUE(std::filesystem::exists(run / "telemetry.mcap"));

  std::map<std::string, json> results;
  for (const std::string data : {"telemetry.csv", "telemetry.mcap"}) {
    const auto out = server.dir() / ("compare_" + data);
    const auto [rc, text] =
        hilbench(server.dir(), {"compare", "--model", hil::test::source_path("configs/plant/nominal.yaml").string(), "--data",
                                (run / data).string(), "--out", out.string(), "--quiet"});
    ASSERT_EQ(rc, 0) << text;
    results[data] = json::parse(hil::test::slurp(out / "compare.json"));
  }
  const json& csv = results["telemetry.csv"];
  const json& mcap = results["telemetry.mcap"];
  ASSERT_TRUE(csv.contains("fit_pct")) << csv.dump();
  EXPECT_GT(csv["fit_pct"].get<double>(), 50.0) << "a run of the nominal plant fits the nominal model";
  EXPECT_EQ(mcap["fit_pct"], csv["fit_pct"]);
  std::size_t numbers = 0;
  for (const auto& [key, value] : csv.items()) {
    if (!value.is_number() || key == "wall_s") continue;  // wall_s: how long compare took
    ++numbers;
    EXPECT_EQ(mcap[key], value) << key;
  }
  EXPECT_GE(numbers, 5u);

  // The report of the folder with only its MCAP: the same table of the run.
  const auto only_mcap = server.dir() / "only_mcap";
  std::filesystem::create_directories(only_mcap);
  for (const auto& f : {"run.json", "telemetry.mcap", "events.jsonl"}) std::filesystem::copy_file(run / f, only_mcap / f);
  const auto [rc_csv, table_csv] = hilbench(server.dir(), {"report", run.string(), "--out", (server.dir() / "a.html").string()});
  const auto [rc_mcap, table_mcap] =
      hilbench(server.dir(), {"report", only_mcap.string(), "--out", (server.dir() / "b.html").string()});
  ASSERT_EQ(rc_csv, 0) << table_csv;
  ASSERT_EQ(rc_mcap, 0) << table_mcap;
  const auto rows_of = [](const std::string& t) { return t.substr(0, t.find("report:")); };
  EXPECT_EQ(rows_of(table_mcap), rows_of(table_csv));
  EXPECT_NE(table_csv.find("adaptive"), std::string::npos) << table_csv;

  // The bytes, against the spec: magic at both ends, the header record first, the footer's
  // summary offsets pointing at records, its CRC over the summary and itself.
  const std::string b = slurp_bytes(run / "telemetry.mcap");
  const std::string magic("\x89MCAP0\r\n", 8);
  ASSERT_GT(b.size(), 8u + 9 + 29 + 8);
  EXPECT_EQ(b.substr(0, 8), magic);
  EXPECT_EQ(b.substr(b.size() - 8), magic);
  EXPECT_EQ(b[8], '\x01') << "the header record follows the magic";
  const std::size_t footer = b.size() - 8 - 29;
  ASSERT_EQ(b[footer], '\x02');
  EXPECT_EQ(le64(b, footer + 1), 20u);
  const std::uint64_t summary_start = le64(b, footer + 9), offsets_start = le64(b, footer + 17);
  ASSERT_LT(summary_start, offsets_start);
  ASSERT_LT(offsets_start, footer);
  EXPECT_EQ(b[summary_start - 13], '\x0f') << "Data End (4 bytes) ends where the summary starts";
  EXPECT_EQ(b[summary_start], '\x03') << "the summary starts with the schemas";
  EXPECT_EQ(b[offsets_start], '\x0e') << "then the summary offsets";
  EXPECT_EQ(le32(b, footer + 25), hil::mcap::crc32(b.substr(summary_start, footer + 25 - summary_start)));

  // Its channels are the live stream's: the same topics, schema names and schemas.
  hil::mcap::Reader r(run / "telemetry.mcap");
  hil::mcap::Message m;
  std::size_t messages = 0;
  while (r.next(m)) ++messages;
  EXPECT_FALSE(r.truncated());
  ASSERT_EQ(r.channels().size(), 2u);
  const json advertised = hil::bench::foxglove::advertise()["channels"];
  for (const auto& [id, c] : r.channels()) {
    const auto it = std::find_if(advertised.begin(), advertised.end(), [&](const json& a) { return a["topic"] == c.topic; });
    ASSERT_NE(it, advertised.end()) << c.topic << " is not a live channel";
    EXPECT_EQ((*it)["schema"], r.schemas().at(c.schema_id).data) << c.topic;
    EXPECT_EQ((*it)["schemaName"], r.schemas().at(c.schema_id).name) << c.topic;
  }
  const json units = json::parse(r.schemas().begin()->second.data)["properties"];
  EXPECT_EQ(units["p_meas_mpa"]["unit"], "MPa") << units.dump();
  EXPECT_EQ(units["theta_cmd_deg"]["unit"], "deg");
  std::size_t csv_rows = 0;
  {
    std::ifstream in(run / "telemetry.csv");
    for (std::string line; std::getline(in, line);)
      if (!line.empty() && line[0] != '#') ++csv_rows;
  }
  std::size_t events = hil::test::read_jsonl(run / "events.jsonl").size();
  EXPECT_EQ(messages, csv_rows - 1 + events) << "every row (less the CSV's header) and every event";
  ASSERT_EQ(r.attachments().size(), 1u);
  EXPECT_EQ(r.attachments()[0].second, slurp_bytes(run / "run.json"));
}

// Files written by MCAP's own TypeScript writer (@mcap/core's McapWriter; the fuzz target's seeds):
// read as ours are, a cut one up to its last whole chunk.
TEST(RunMcap, FilesOfAnotherWriterAreRead) {
  const auto seeds = hil::test::source_path("tests/fuzz/corpus/mcap");
  const auto m = hil::analysis::load_measurement(seeds / "written_by_mcap_core");
  ASSERT_EQ(m.rows.size(), 80u);
  EXPECT_DOUBLE_EQ(m.rows.t_s[79], 0.079);
  EXPECT_DOUBLE_EQ(m.rows.p_meas_pa[20], 1.5e6);
  EXPECT_EQ(m.metadata, (std::vector<std::pair<std::string, std::string>>{}));
  hil::mcap::Reader r(seeds / "written_by_mcap_core");
  hil::mcap::Message msg;
  std::size_t n = 0;
  while (r.next(msg)) ++n;
  EXPECT_EQ(n, 80u + 4) << "80 rows and 4 events";
  ASSERT_EQ(r.attachments().size(), 1u);
  EXPECT_EQ(r.attachments()[0].second, R"({"outcome":"completed"})");
  ASSERT_EQ(r.metadata().size(), 1u);
  EXPECT_EQ(r.metadata()[0].second, (hil::mcap::KeyValues{{"yaml", "name: x\n"}}));
  hil::mcap::Reader cut(seeds / "cut_inside_a_chunk");
  std::size_t rows = 0;
  while (cut.next(msg)) rows += cut.channels().at(msg.channel_id).topic == hil::telemetry::kTopic;
  EXPECT_TRUE(cut.truncated());
  EXPECT_GT(rows, 0u);
  EXPECT_LT(rows, 80u);
}

TEST(RunMcap, HostileFilesAreRefusedNamingTheRecordOffset) {
  hil::test::TempDir dir;
  // A value out of range: the measurement reader names the record of that row.
  const auto bad = make_mcap(dir.path() / "bad_value.mcap", 300, 150);
  const std::string e = error_of([&] { hil::analysis::load_measurement(bad); });
  EXPECT_NE(e.find(bad.string() + ": record at byte " + std::to_string(offset_of_message(bad, 150)) +
                   " (/hilbench/telemetry): "
                   "column 'p_meas_mpa': 500 MPa is outside"),
            std::string::npos)
      << e;
  // A value that is not a number, and a message that is no JSON object.
  const auto text = make_mcap(dir.path() / "text.mcap", 300, 20, "\"high\"");
  EXPECT_NE(error_of([&] { hil::analysis::load_measurement(text); }).find("column 'p_meas_mpa': not a number: \"high\""),
            std::string::npos);
  {
    hil::mcap::Writer w(dir.path() / "array.mcap", "");
    const auto ch =
        w.add_channel(w.add_schema("s", "jsonschema", R"({"properties":{"t_s":{},"theta_cmd_deg":{},"p_meas_mpa":{}}})"),
                      hil::telemetry::kTopic, "json");
    w.message(ch, 0, "[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]");
  }
  EXPECT_NE(error_of([&] { hil::analysis::load_measurement(dir.path() / "array.mcap"); }).find("record at byte "),
            std::string::npos);
  // A schema without a required column names what it has.
  {
    hil::mcap::Writer w(dir.path() / "no_p.mcap", "");
    w.add_channel(w.add_schema("s", "jsonschema", R"({"properties":{"t_s":{},"theta_cmd_deg":{}}})"), hil::telemetry::kTopic,
                  "json");
  }
  EXPECT_NE(error_of([&] {
              hil::analysis::load_measurement(dir.path() / "no_p.mcap");
            }).find("its schema has no column 'p_meas_mpa' (it has: t_s, theta_cmd_deg)"),
            std::string::npos);
  // No telemetry channel at all, and no MCAP at all.
  {
    hil::mcap::Writer w(dir.path() / "other.mcap", "");
    w.add_channel(0, "/camera", "json");
  }
  EXPECT_NE(error_of([&] {
              hil::analysis::load_measurement(dir.path() / "other.mcap");
            }).find("no channel '/hilbench/telemetry' (the file has: /camera)"),
            std::string::npos);

  // A damaged chunk: one byte of a message flipped; its CRC says so, naming the chunk's offset.
  // Uncompressed chunks (as other writers may write them): a message's offset is in the file.
  const auto good = make_mcap(dir.path() / "good.mcap", 300, SIZE_MAX, "", hil::mcap::Compression::none);
  std::string bytes = slurp_bytes(good);
  const std::uint64_t at = offset_of_message(good, 10);
  bytes[at + 30] ^= 0x01;
  std::ofstream(dir.path() / "damaged.mcap", std::ios::binary) << bytes;
  const std::string damaged = error_of([&] { hil::analysis::load_measurement(dir.path() / "damaged.mcap"); });
  EXPECT_NE(damaged.find("record at byte "), std::string::npos) << damaged;
  EXPECT_NE(damaged.find("CRC-32 does not match"), std::string::npos) << damaged;

  // Cut inside the middle of the file: the rows of every whole chunk before the cut, no more.
  bytes = slurp_bytes(good);
  const std::uint64_t cut = offset_of_message(good, 200);
  std::ofstream(dir.path() / "cut.mcap", std::ios::binary) << bytes.substr(0, cut);
  // The last whole record before the cut, by the spec's framing (opcode, u64 length) walked here.
  std::uint64_t whole_end = 8;
  for (std::uint64_t at = 8; at + 9 <= cut && at + 9 + le64(bytes, at + 1) <= cut; at += 9 + le64(bytes, at + 1))
    whole_end = at + 9 + le64(bytes, at + 1);
  hil::mcap::Reader full(good);
  hil::mcap::Message m;
  std::size_t expected = 0;
  while (full.next(m)) expected += m.offset < whole_end ? 1 : 0;
  hil::mcap::Reader cut_reader(dir.path() / "cut.mcap");
  std::size_t whole = 0;
  while (cut_reader.next(m)) ++whole;
  EXPECT_TRUE(cut_reader.truncated());
  EXPECT_EQ(whole, expected);
  EXPECT_GT(whole, 50u);
  EXPECT_LT(whole, 200u) << "the chunk the cut is in is not read";
  const auto recovered = hil::analysis::load_measurement(dir.path() / "cut.mcap");
  EXPECT_EQ(recovered.rows.size(), whole);
  EXPECT_DOUBLE_EQ(recovered.rows.t_s.back(), static_cast<double>(whole - 1) * 1e-3);
}
