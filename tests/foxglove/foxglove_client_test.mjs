// The real `hilbench serve`, watched with the Foxglove WebSocket protocol's own client
// (@foxglove/ws-protocol): the server advertises JSON channels with JSON Schema; a client that
// subscribes to the pressure channel during a run receives Message Data with increasing
// timestamps whose payloads match the schema; the run's start arrives on the events channel;
// requests the server does not understand get a status message and the connection stays.
//   node foxglove_client_test.mjs HILBENCH_EXE SOURCE_DIR
import { spawn } from "node:child_process";
import { mkdtempSync, readFileSync, existsSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS: no named exports under node

import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

const [exe, sourceDir] = process.argv.slice(2);
const want = 40; // pressure messages: 2 s of the run at 20 Hz
const dir = mkdtempSync(join(tmpdir(), "hil-foxglove-"));
let server;
let failed = false;

function fail(message) {
  failed = true;
  console.error("FAIL: " + message);
}
function finish() {
  if (server && server.exitCode === null) server.kill("SIGTERM");
  if (failed && existsSync(join(dir, "server.log"))) console.error("---- server log ----\n" + readFileSync(join(dir, "server.log"), "utf8"));
  rmSync(dir, { recursive: true, force: true });
  process.exit(failed ? 1 : 0);
}
const deadline = setTimeout(() => {
  fail("timed out after 120 s");
  finish();
}, 120_000);

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function main() {
  const log = (await import("node:fs")).openSync(join(dir, "server.log"), "a");
  server = spawn(exe, ["serve", "--listen", "127.0.0.1:0", "--configs", join(sourceDir, "configs"), "--runs-dir", join(dir, "runs"),
    "--port-file", join(dir, "port")], { stdio: ["ignore", log, log] });
  for (let i = 0; i < 600 && !existsSync(join(dir, "port")); ++i) await sleep(100);
  if (!existsSync(join(dir, "port"))) return fail("hilbench serve did not start");
  const port = Number(readFileSync(join(dir, "port"), "utf8"));
  const base = `http://127.0.0.1:${port}`;

  const client = new FoxgloveClient({ ws: new WebSocket(`ws://127.0.0.1:${port}/api/telemetry`, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
  const statuses = [];
  const events = [];
  const pressure = [];
  let serverInfo;
  let channels;
  client.on("error", (e) => fail("client error: " + e));
  client.on("serverInfo", (info) => (serverInfo = info));
  client.on("status", (s) => statuses.push(s));
  const subscribed = new Promise((resolve) => {
    client.on("advertise", (list) => {
      channels = list;
      const p = list.find((c) => c.topic === "/hilbench/pressure");
      const e = list.find((c) => c.topic === "/hilbench/events");
      if (!p || !e) return fail("pressure or events channel not advertised: " + JSON.stringify(list.map((c) => c.topic)));
      resolve({ pressure: client.subscribe(p.id), events: client.subscribe(e.id), schema: JSON.parse(p.schema) });
    });
  });
  const subs = await subscribed;
  const decoder = new TextDecoder();
  client.on("message", ({ subscriptionId, timestamp, data }) => {
    const payload = JSON.parse(decoder.decode(data));
    if (subscriptionId === subs.pressure) pressure.push({ timestamp, payload });
    else if (subscriptionId === subs.events) events.push(payload);
    else fail("a message for subscription " + subscriptionId + ", which was never made");
  });

  if (serverInfo?.name !== "hilbench") fail("serverInfo: " + JSON.stringify(serverInfo));
  for (const c of channels) {
    if (c.encoding !== "json" || c.schemaEncoding !== "jsonschema") fail(`channel ${c.topic}: encoding ${c.encoding}/${c.schemaEncoding}`);
  }
  const schemaFields = Object.keys(subs.schema.properties ?? {});
  for (const f of ["t_s", "p_ref_mpa", "p_meas_mpa"]) if (!schemaFields.includes(f)) fail("pressure schema lacks " + f);

  // A request the server does not understand: a status message, and the stream goes on.
  client.subscribe(9999);

  const start = await fetch(`${base}/api/start`, { method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ campaign: "paper_adaptive", runs: ["adaptive"] }) });
  if (start.status !== 202) return fail("start: " + start.status + " " + (await start.text()));

  for (let i = 0; i < 600 && pressure.length < want; ++i) await sleep(100);
  await fetch(`${base}/api/abort`, { method: "POST", headers: { "content-type": "application/json" }, body: "{}" });

  if (pressure.length < want) fail(`only ${pressure.length} pressure messages in 60 s`);
  for (let i = 1; i < pressure.length; ++i) {
    if (!(pressure[i].timestamp > pressure[i - 1].timestamp)) {
      fail(`timestamps not increasing at ${i}: ${pressure[i - 1].timestamp} then ${pressure[i].timestamp}`);
      break;
    }
  }
  for (const { timestamp, payload } of pressure) {
    if (Object.keys(payload).sort().join() !== [...schemaFields].sort().join()) fail("payload fields differ from the schema: " + JSON.stringify(payload));
    const ts = Number(timestamp) / 1e9;
    if (Math.abs(ts - payload.t_s) > 1e-6) fail(`timestamp ${ts} s is not the row's t_s ${payload.t_s}`);
    if (!(payload.p_meas_mpa > 0.5 && payload.p_meas_mpa < 2.5)) fail("implausible p_meas_mpa " + payload.p_meas_mpa);
  }
  if (!events.some((e) => e.type === "run_start")) fail("no run_start on the events channel: " + JSON.stringify(events));
  if (!statuses.some((s) => s.level === 2 && /channel 9999/.test(s.message))) fail("no error status for channel 9999: " + JSON.stringify(statuses));
  console.log(`pressure messages: ${pressure.length}, t ${pressure[0]?.payload.t_s} .. ${pressure.at(-1)?.payload.t_s} s; events: ${events.map((e) => e.type).join(", ")}; statuses: ${statuses.length}`);
  client.close();
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(deadline);
  finish();
});
