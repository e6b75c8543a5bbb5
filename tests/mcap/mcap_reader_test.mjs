// A run's telemetry.mcap, read by MCAP's own TypeScript reader (@mcap/core, its zstd chunks
// decompressed by @mcap/support's handlers) against the real `hilbench serve`:
//  1. a completed run of paper_adaptive: zstd chunks, the file smaller than telemetry.csv; the
//     indexed reader takes its summary (statistics, chunk indexes, footer CRC); the stream reader,
//     checking every chunk's CRC, yields every message in file order; every message is valid
//     against its channel's JSON Schema (ajv); the telemetry messages are telemetry.csv's rows,
//     value for value, logged at wall-clock times (the run's start plus t_s / speed, within the
//     run's start and stop); the events are events.jsonl's lines; the campaign, plant and rig
//     snapshot are metadata records equal to run.json's, and run.json is an attachment, byte for byte;
//  2. a copy of that file cut inside a chunk, and a run whose server was killed with SIGKILL
//     mid-way: the stream reader recovers every message of every whole chunk, counted here
//     independently by walking the file's records, and they are telemetry.csv's first rows;
//  3. after a restart of the server, that killed run's file has its summary and footer: the
//     indexed reader opens it and reads every message the stream reader recovered.
//   node mcap_reader_test.mjs HILBENCH_EXE SOURCE_DIR
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, existsSync, rmSync, openSync, statSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import AjvModule from "ajv";

const Ajv = AjvModule.default ?? AjvModule; // CommonJS under node
const [exe, sourceDir] = process.argv.slice(2);
const dir = mkdtempSync(join(tmpdir(), "hil-mcap-"));
let server;
let failed = false;
const decoder = new TextDecoder();
const decompressHandlers = await loadDecompressHandlers();

function fail(message) {
  failed = true;
  console.error("FAIL: " + message);
}
function check(cond, message) {
  if (!cond) fail(message);
  return cond;
}
function finish() {
  if (server && server.exitCode === null) server.kill("SIGKILL");
  if (failed && existsSync(join(dir, "server.log"))) console.error("---- server log ----\n" + readFileSync(join(dir, "server.log"), "utf8"));
  rmSync(dir, { recursive: true, force: true });
  process.exit(failed ? 1 : 0);
}
const deadline = setTimeout(() => {
  fail("timed out after 240 s");
  finish();
}, 240_000);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// The run's log clock, from its metadata record "clock" (start_unix_ns, speed).
function logClock(clockMetadata) {
  return { start: BigInt(clockMetadata?.get("start_unix_ns") ?? "0"), speed: Number(clockMetadata?.get("speed") ?? "0") };
}

async function startServer() {
  const log = openSync(join(dir, "server.log"), "a");
  rmSync(join(dir, "port"), { force: true });
  server = spawn(exe, ["serve", "--listen", "127.0.0.1:0", "--configs", join(sourceDir, "configs"), "--runs-dir", join(dir, "runs"),
    "--port-file", join(dir, "port")], { stdio: ["ignore", log, log] });
  for (let i = 0; i < 600 && !existsSync(join(dir, "port")); ++i) await sleep(100);
  if (!existsSync(join(dir, "port"))) throw new Error("hilbench serve did not start");
  return `http://127.0.0.1:${Number(readFileSync(join(dir, "port"), "utf8"))}`;
}
async function start(base, speed) {
  const r = await fetch(`${base}/api/start`, { method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ campaign: "paper_adaptive", runs: ["adaptive"], speed }) });
  if (r.status !== 202) throw new Error("start: " + r.status + " " + (await r.text()));
}
// The folder of the run under way, from the server's status.
async function runningRun(base) {
  for (let i = 0; i < 600; ++i) {
    const s = await (await fetch(`${base}/api/status`)).json();
    if (s.run_dir) return join(dir, "runs", s.run_dir);
    await sleep(50);
  }
  throw new Error("no run under way");
}

// telemetry.csv: its column names and its rows as text cells ("# key: value" lines skipped).
function readCsv(file) {
  const lines = readFileSync(file, "utf8").split("\n").filter((l) => l !== "" && !l.startsWith("#"));
  return { names: lines[0].split(","), rows: lines.slice(1).map((l) => l.split(",")) };
}

// The file's top-level records walked by hand (the spec's framing: opcode u8, length u64 LE):
// where the last whole record ends, and the Message records inside every whole chunk.
function wholeChunks(buf) {
  const view = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  let at = 8, end = 8, messages = 0, chunks = 0;
  while (at + 9 <= buf.length) {
    const op = buf[at];
    const len = Number(view.getBigUint64(at + 1, true));
    if (at + 9 + len > buf.length) break;
    if (op === 0x06) {
      ++chunks;
      const uncompressed = view.getBigUint64(at + 9 + 16, true);
      let p = at + 9 + 8 + 8 + 8 + 4;
      const compression = decoder.decode(buf.subarray(p + 4, p + 4 + view.getUint32(p, true)));
      p += 4 + view.getUint32(p, true);
      const size = Number(view.getBigUint64(p, true));
      p += 8;
      check(compression === "zstd", `chunk at ${at}: compression '${compression}'`);
      const records = compression === "zstd" ? decompressHandlers.zstd(buf.subarray(p, p + size), uncompressed) : buf.subarray(p, p + size);
      const rv = new DataView(records.buffer, records.byteOffset, records.byteLength);
      for (let q = 0; q < records.length; q += 9 + Number(rv.getBigUint64(q + 1, true))) if (records[q] === 0x05) ++messages;
    }
    at += 9 + len;
    end = at;
  }
  return { end, messages, chunks };
}

// Every message the stream reader yields (CRCs checked), and whether it reached the file's end.
function streamRead(buf) {
  const reader = new McapStreamReader({ validateCrcs: true, decompressHandlers });
  reader.append(buf);
  const channels = new Map(), schemas = new Map(), messages = [], metadata = new Map();
  for (let r; (r = reader.nextRecord()); ) {
    if (r.type === "Metadata") metadata.set(r.name, r.metadata);
    else if (r.type === "Schema") schemas.set(r.id, r);
    else if (r.type === "Channel") channels.set(r.id, r);
    else if (r.type === "Message") messages.push({ topic: channels.get(r.channelId).topic, logTime: r.logTime, data: r.data, schema: schemas.get(channels.get(r.channelId).schemaId) });
  }
  return { messages, metadata, done: reader.done(), remaining: reader.bytesRemaining() };
}

const ajv = new Ajv({ allowUnionTypes: true });
ajv.addKeyword("unit"); // the schemas' unit of each column: an annotation
const validators = new Map();
function validate(m) {
  if (!validators.has(m.schema.id)) {
    check(m.schema.encoding === "jsonschema", `schema ${m.schema.name}: encoding ${m.schema.encoding}`);
    validators.set(m.schema.id, ajv.compile(JSON.parse(decoder.decode(m.schema.data))));
  }
  const v = validators.get(m.schema.id);
  const payload = JSON.parse(decoder.decode(m.data));
  if (!v(payload)) fail(`${m.topic}: ${decoder.decode(m.data)} is not valid against its schema: ${ajv.errorsText(v.errors)}`);
  return payload;
}

// The telemetry messages against the CSV's rows, from the first: same count, same values.
function sameRows(label, telemetry, csv, wantAll, clock) {
  check(clock.start > 1_700_000_000_000_000_000n && clock.speed > 0, `${label}: log clock ${clock.start} ns, speed ${clock.speed}`);
  if (wantAll) check(telemetry.length === csv.rows.length, `${label}: ${telemetry.length} telemetry messages, telemetry.csv has ${csv.rows.length} rows`);
  else check(telemetry.length <= csv.rows.length, `${label}: more messages (${telemetry.length}) than CSV rows (${csv.rows.length})`);
  let bad = 0;
  telemetry.forEach(({ payload, logTime }, i) => {
    const row = csv.rows[i];
    if (!row) return;
    for (const [k, name] of csv.names.entries()) {
      if (payload[name] !== Number(row[k]) && ++bad <= 3) fail(`${label}: row ${i} column ${name}: MCAP ${payload[name]}, CSV ${row[k]}`);
    }
    const t = clock.start + BigInt(Math.round((Number(row[0]) * 1e9) / clock.speed));
    if ((logTime > t ? logTime - t : t - logTime) > 1n && ++bad <= 3) fail(`${label}: row ${i}: log time ${logTime} ns, t_s ${row[0]}: expected ${t}`);
  });
  if (Object.keys(telemetry[0]?.payload ?? {}).join() !== csv.names.join()) fail(`${label}: fields ${Object.keys(telemetry[0]?.payload ?? {})} vs CSV ${csv.names}`);
}

// The indexed reader over a file's bytes (it reads the footer, checks its CRC and the magic).
function openIndexed(file) {
  return McapIndexedReader.Initialize({ readable: { size: async () => BigInt(file.length),
    read: async (offset, length) => file.subarray(Number(offset), Number(offset + length)) }, decompressHandlers });
}

async function completedRun(base) {
  await start(base, 10);
  const run = await runningRun(base);
  let status;
  for (let i = 0; i < 1200; ++i) {
    status = await (await fetch(`${base}/api/status`)).json();
    if (status.state === "idle" && status.last) break;
    await sleep(100);
  }
  if (status.last?.outcome !== "completed") throw new Error("the run did not complete: " + JSON.stringify(status));
  const file = readFileSync(join(run, "telemetry.mcap"));
  const csv = readCsv(join(run, "telemetry.csv"));
  const events = readFileSync(join(run, "events.jsonl"), "utf8").split("\n").filter((l) => l).map((l) => JSON.parse(l));
  const runJson = readFileSync(join(run, "run.json"));

  // The summary, through the indexed reader (it reads the footer, checks its CRC and the magic).
  const indexed = await openIndexed(file);
  check(file.length < statSync(join(run, "telemetry.csv")).size, `telemetry.mcap ${file.length} bytes, telemetry.csv ${statSync(join(run, "telemetry.csv")).size}`);
  const topics = new Map([...indexed.channelsById.values()].map((c) => [c.topic, c]));
  check(topics.has("/hilbench/telemetry") && topics.has("/hilbench/events") && topics.size === 2, "channels: " + [...topics.keys()]);
  const stats = indexed.statistics;
  check(stats && stats.messageCount === BigInt(csv.rows.length + events.length),
    `statistics: ${stats?.messageCount} messages, expected ${csv.rows.length} rows + ${events.length} events`);
  check(stats?.channelMessageCounts.get(topics.get("/hilbench/telemetry").id) === BigInt(csv.rows.length), "statistics: telemetry count");
  check(indexed.chunkIndexes.length > 1 && stats?.chunkCount === indexed.chunkIndexes.length, `chunks: ${indexed.chunkIndexes.length}`);
  let indexedCount = 0;
  for await (const m of indexed.readMessages({ topics: ["/hilbench/telemetry"] })) ++indexedCount;
  check(indexedCount === csv.rows.length, `indexed reader: ${indexedCount} telemetry messages`);

  const metadata = new Map();
  for await (const m of indexed.readMetadata()) metadata.set(m.name, m.metadata);
  const record = JSON.parse(runJson.toString("utf8"));
  for (const [name, key] of [["campaign", "campaign_yaml"], ["rig", "rig_yaml"], ["plant", "plant_yaml"]]) {
    check(metadata.get(name)?.get("yaml") === record.config[key], `metadata '${name}': yaml differs from run.json's ${key}`);
  }
  check(metadata.get("telemetry")?.get("campaign") === "paper_adaptive", "metadata 'telemetry': " + JSON.stringify([...(metadata.get("telemetry") ?? [])]));
  const attachments = [];
  for await (const a of indexed.readAttachments({ validateCrcs: true })) attachments.push(a);
  check(attachments.length === 1 && attachments[0].name === "run.json" && attachments[0].mediaType === "application/json" &&
    Buffer.from(attachments[0].data).equals(runJson), "attachment run.json differs from the run's run.json");
  check(record.outcome === "completed", "run.json in the file is the final one: " + record.outcome);

  // Every message, in file order, through the stream reader.
  const all = streamRead(file);
  check(all.done, "the stream reader did not reach the file's end");
  const telemetry = [], eventsRead = [];
  for (const m of all.messages) {
    const payload = validate(m);
    if (m.topic === "/hilbench/telemetry") telemetry.push({ payload, logTime: m.logTime });
    else eventsRead.push(payload);
  }
  const clock = logClock(metadata.get("clock"));
  check(clock.speed === 10, "clock speed " + clock.speed);
  sameRows("completed run", telemetry, csv, true, clock);
  const [first, last] = [telemetry[0].logTime, telemetry[telemetry.length - 1].logTime];
  const [startNs, stopNs] = [BigInt(Date.parse(record.start_utc)) * 1_000_000n, BigInt(Date.parse(record.stop_utc)) * 1_000_000n];
  check(first >= startNs - 1_000_000_000n && last <= stopNs + 1_000_000_000n,
    `log times ${first}..${last} ns are not within the run's ${record.start_utc}..${record.stop_utc}`);
  check(JSON.stringify(eventsRead) === JSON.stringify(events), `events differ from events.jsonl: ${eventsRead.length} vs ${events.length} lines`);
  check(events.some((e) => e.kind === "run_start"), "no run_start in events.jsonl");

  // A copy cut in the middle of a chunk two from the end: every whole chunk before it is read.
  const cutChunk = indexed.chunkIndexes[indexed.chunkIndexes.length - 2];
  const cut = file.subarray(0, Number(cutChunk.chunkStartOffset + cutChunk.chunkLength / 2n));
  const walked = wholeChunks(cut);
  const recovered = streamRead(cut);
  check(!recovered.done && recovered.remaining === cut.length - walked.end, `cut copy: ${recovered.remaining} bytes left unread, the last whole record ends ${cut.length - walked.end} bytes before the cut`);
  check(recovered.messages.length === walked.messages, `cut copy: ${recovered.messages.length} messages read, the whole chunks hold ${walked.messages}`);
  sameRows("cut copy", recovered.messages.filter((m) => m.topic === "/hilbench/telemetry").map((m) => ({ payload: validate(m), logTime: m.logTime })), csv, false, clock);
  console.log(`completed run: ${csv.rows.length} rows, ${events.length} events, ${indexed.chunkIndexes.length} chunks, ${file.length} bytes; ` +
    `cut at ${cut.length}: ${recovered.messages.length} messages in ${walked.chunks} whole chunks`);
}

async function killedRun(base) {
  await start(base, 1);
  const run = await runningRun(base);
  // Killed once the CSV holds 1.5 s of rows (it and the MCAP are flushed together).
  for (let i = 0; i < 600; ++i) {
    const csv = existsSync(join(run, "telemetry.csv")) ? readCsv(join(run, "telemetry.csv")) : { rows: [] };
    if (csv.rows.length >= 1500) break;
    await sleep(100);
  }
  server.kill("SIGKILL");
  await new Promise((r) => (server.exitCode !== null || server.signalCode !== null ? r() : server.once("exit", r)));
  const file = readFileSync(join(run, "telemetry.mcap"));
  const csv = readCsv(join(run, "telemetry.csv"));
  const walked = wholeChunks(file);
  const recovered = streamRead(file);
  check(!recovered.done, "the killed run's file has a footer");
  check(recovered.remaining === file.length - walked.end, `killed run: ${recovered.remaining} bytes unread, ${file.length - walked.end} after the last whole record`);
  check(walked.chunks >= 5 && recovered.messages.length === walked.messages, `killed run: ${recovered.messages.length} messages read, ${walked.messages} in ${walked.chunks} whole chunks`);
  const telemetry = recovered.messages.filter((m) => m.topic === "/hilbench/telemetry").map((m) => ({ payload: validate(m), logTime: m.logTime }));
  check(telemetry.length >= 1000, `killed run: only ${telemetry.length} rows recovered`);
  sameRows("killed run", telemetry, csv, false, logClock(recovered.metadata.get("clock")));
  console.log(`killed run: ${file.length} bytes, ${walked.chunks} whole chunks, ${telemetry.length} rows recovered of ${csv.rows.length} in the CSV`);
  return { run, recovered };
}

// The next server's start finishes the killed run's file: the indexed reader opens it, and reads
// every message the stream reader recovered from the cut file, in its whole chunks.
async function restartedRun(killed) {
  await startServer();
  let record;
  for (let i = 0; i < 100; ++i) {  // the start's scan of the runs folder
    record = JSON.parse(readFileSync(join(killed.run, "run.json"), "utf8"));
    if (record.outcome !== "running") break;
    await sleep(100);
  }
  check(record.outcome === "interrupted", "the killed run's outcome: " + record.outcome);
  const finished = record.interrupted?.["telemetry.mcap"];
  check(finished && finished.messages === killed.recovered.messages.length,
    "run.json's interrupted record of telemetry.mcap: " + JSON.stringify(finished) + `, ${killed.recovered.messages.length} messages recovered`);
  const file = readFileSync(join(killed.run, "telemetry.mcap"));
  let indexed;
  try {
    indexed = await openIndexed(file);
  } catch (e) {
    fail("the indexed reader refuses the finished file: " + e);
    return;
  }
  check(indexed.statistics?.messageCount === BigInt(killed.recovered.messages.length),
    `finished file: statistics say ${indexed.statistics?.messageCount} messages, ${killed.recovered.messages.length} were in whole chunks`);
  const read = [];
  for await (const m of indexed.readMessages()) read.push(m);
  check(read.length === killed.recovered.messages.length, `finished file: the indexed reader read ${read.length} messages`);
  const keys = (ms) => ms.map((m) => `${m.logTime} ${decoder.decode(m.data)}`).sort();
  check(JSON.stringify(keys(read)) === JSON.stringify(keys(killed.recovered.messages)), "finished file: the indexed reader's messages are not the recovered ones");
  const all = streamRead(file);
  check(all.done && all.messages.length === read.length, `finished file: the stream reader reached its end (${all.done}) with ${all.messages.length} messages`);
  console.log(`restarted: the killed run's file finished (${file.length} bytes, ${indexed.chunkIndexes.length} chunks, ${read.length} messages)`);
}

async function main() {
  const base = await startServer();
  await completedRun(base);
  await restartedRun(await killedRun(base));
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(deadline);
  finish();
});
