// The operator console an operator can trust (issue 40), in Debian's Chromium against the real
// `hilbench serve`:
//  - idle: ABORT and the injections are disabled; a campaign started through the API (not the
//    page) shows in the controls as it runs (its campaign, rig and only its runs ticked);
//  - the server killed mid-run: a red "LINK LOST" banner and the state "unknown"; ABORT says
//    "abort NOT delivered" and retries; the server started again: the banner clears, the state is
//    idle again, and the retried abort says when it was answered;
//  - an abort on the sim rig: SAFE latched on screen with its reason until acknowledged, also
//    after the run has ended (the sim rig holds its safe state 200 ms only);
//  - require_operator (a rig file with require_operator: true, operator_timeout_s): the only client
//    goes quiet mid-run and the run ends in the safe state with "operator link lost", and
//    telemetry.csv holds every period it ran;
//  - events: a run of 10 000 overruns (and operator events among them) read through
//    GET /api/runs/{id}/events by offset lists every operator event once and the overruns as
//    one summary per second; the page's event fetches do not grow with the run's length;
//  - a run's Compare/Diagnose model picker is set to the run's own plant (soak_random: constant_volume).
// Times (kill to banner, quiet to safe state) and bytes are printed, not asserted: the machine is busy.
//   node console_link_test.mjs HILBENCH_EXE SOURCE_DIR      (HIL_KEEP_SCREENSHOTS=1 keeps the temp dir)
import { appendFileSync, mkdirSync, readdirSync, readFileSync, symlinkSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { dataset, harness, sleep } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const h = harness("hil-console-link-", 280);
const { dir, fail, waitFor } = h;
const kOperatorTimeoutS = 2;
const measured = [];

// The shipped configs, plus a sim rig that requires an operator.
function configs() {
  const c = join(dir, "configs");
  mkdirSync(join(c, "rigs"), { recursive: true });
  for (const sub of ["campaigns", "plant"]) symlinkSync(join(sourceDir, "configs", sub), join(c, sub));
  const sim = readFileSync(join(sourceDir, "configs", "rigs", "sim.yaml"), "utf8");
  writeFileSync(join(c, "rigs", "sim.yaml"), sim);
  writeFileSync(join(c, "rigs", "sim_attended.yaml"), sim + `\nrequire_operator: true\noperator_timeout_s: ${kOperatorTimeoutS}\n`);
  return c;
}

const startServer = () => h.startServer(exe, join(dir, "configs"));
const text = (page, sel) => page.$eval(sel, (e) => (e.hidden ? "" : e.textContent));

async function call(base, method, path, payload) {
  const res = await fetch(base + path, { method, headers: payload ? { "Content-Type": "application/json" } : {},
    body: payload ? JSON.stringify(payload) : undefined });
  const body = await res.text();
  let json = null;
  try {
    json = JSON.parse(body);
  } catch (e) {
    json = null;
  }
  return { status: res.status, json, bytes: body.length };
}

// Every event of a run through the feed, following next_offset.
async function feedAll(base, id) {
  const all = { events: [], summaries: [], bytes: 0, looks: 0 };
  for (let offset = 0; ;) {
    const r = await call(base, "GET", `/api/runs/${encodeURIComponent(id)}/events?offset=${offset}`);
    if (r.status !== 200) throw new Error(`events?offset=${offset}: ${r.status} ${JSON.stringify(r.json)}`);
    all.bytes += r.bytes;
    ++all.looks;
    all.events.push(...r.json.events);
    all.summaries.push(...r.json.summaries);
    if (r.json.next_offset >= r.json.size || r.json.next_offset === offset) return { ...all, size: r.json.size };
    offset = r.json.next_offset;
  }
}

async function main() {
  configs();
  let base = await startServer();
  const browser = await h.launch();
  const page = await browser.newPage();
  const problems = [];
  page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  await page.setViewport({ width: 1400, height: 900 });
  await page.goto(base + "/", { waitUntil: "load" });

  // Idle: the state comes from the stream, and the controls that cannot act are disabled.
  if (!(await waitFor(page, "idle from the stream", () => document.body.dataset.state === "idle" && document.body.dataset.link === "live"))) return;
  if (!(await waitFor(page, "campaigns listed", () => [...document.querySelectorAll("#campaign option")].some((o) => o.value === "paper_adaptive")))) return;
  const idle = await page.evaluate(() => ({ abort: document.getElementById("abort").disabled, gap: document.getElementById("inject-gap").disabled,
    start: document.getElementById("start").disabled }));
  if (!idle.abort || !idle.gap || idle.start) fail("controls while idle: " + JSON.stringify(idle));

  // A campaign started through the API shows in the controls: its campaign, its rig, its one run.
  await page.select("#campaign", "soak_random").catch(() => {});  // another choice first, if there is one
  const started = await call(base, "POST", "/api/start", { campaign: "paper_adaptive", rig: "sim", runs: ["adaptive"], speed: 0.5 });
  if (started.status !== 202 && started.status !== 200) return fail("start through the API: " + JSON.stringify(started));
  if (!(await waitFor(page, "running from the stream", () => document.body.dataset.state === "running"))) return;
  await waitFor(page, "the controls show what runs", () => {
    const ticked = [...document.querySelectorAll("#runs-choice input")].filter((b) => b.checked).map((b) => b.value);
    return document.getElementById("campaign").value === "paper_adaptive" && document.getElementById("rig").value === "sim" &&
      ticked.join(",") === "adaptive" && document.getElementById("campaign").disabled && !document.getElementById("abort").disabled &&
      !document.getElementById("inject-gap").disabled && document.getElementById("start").disabled;
  });
  await sleep(1000);

  // The server dies mid-run: the banner, the unknown state, and an abort that says it was not delivered.
  const killedAt = Date.now();
  h.server.kill("SIGKILL");
  if (!(await waitFor(page, "the link-lost banner", () => document.body.dataset.link === "lost" &&
      /LINK LOST/.test(document.getElementById("link-lost").textContent) && !document.getElementById("link-lost").hidden))) return;
  const bannerMs = Date.now() - killedAt;
  measured.push(`kill to banner ${bannerMs} ms`);
  const lost = await dataset(page);
  if (lost.state !== "unknown") fail("the state while the link is lost: " + lost.state);
  if (!/state unknown/i.test(await text(page, "#state"))) fail("the badge while the link is lost: " + (await text(page, "#state")));
  // The banner counts the time since the last message.
  await sleep(1200);
  const banner = await text(page, "#link-lost");
  const silentS = Number((/for (\d+(\.\d+)?) s/.exec(banner) || [])[1]);
  if (!(silentS >= 1)) fail("the banner does not count the silence: " + JSON.stringify(banner));
  await page.click("#abort");
  if (!(await waitFor(page, "abort NOT delivered", () => document.body.dataset.abort === "not-delivered" &&
      /abort NOT delivered/.test(document.getElementById("message").textContent)))) return;
  await waitFor(page, "the abort retried", () => /attempt [2-9]/.test(document.getElementById("message").textContent), undefined, 10_000);
  if (!/ABORT \(retrying\)/.test(await text(page, "#abort"))) fail("the ABORT button while retrying: " + (await text(page, "#abort")));

  // The server again: the banner clears, the state is right, the retried abort is answered.
  const restartAt = Date.now();
  base = await startServer();
  if (!(await waitFor(page, "the link restored", () => document.body.dataset.link === "live" && document.getElementById("link-lost").hidden, undefined, 30_000))) return;
  measured.push(`restart to link live ${Date.now() - restartAt} ms`);
  await waitFor(page, "idle after the restart", () => document.body.dataset.state === "idle");
  await waitFor(page, "the retried abort answered", () => document.body.dataset.abort === "answered" &&
    /abort answered at \d\d:\d\d:\d\d \(attempt \d+\)/.test(document.getElementById("message").textContent));
  const runsAfter = (await call(base, "GET", "/api/runs")).json.runs;
  if (runsAfter[0]?.outcome !== "interrupted") fail("the killed run's record: " + JSON.stringify(runsAfter[0]));

  // An abort on the sim rig: SAFE latched with its reason, kept after the run ended, until acknowledged.
  await page.select("#campaign", "paper_adaptive");
  await waitFor(page, "the controls enabled again", () => !document.getElementById("start").disabled && !document.getElementById("campaign").disabled);
  for (const r of await page.$$eval("#runs-choice input", (b) => b.map((x) => x.value))) {
    const checked = await page.$eval(`#runs-choice input[value="${r}"]`, (b) => b.checked);
    if ((r === "adaptive") !== checked) await page.click(`#runs-choice input[value="${r}"]`);
  }
  await page.click("#start");
  if (!(await waitFor(page, "running again", () => document.body.dataset.state === "running"))) return;
  await sleep(500);
  await page.keyboard.press("Escape");  // the ABORT shortcut
  if (!(await waitFor(page, "SAFE latched with its reason", () => document.body.dataset.latched === "safe" &&
      /SAFE STATE.*operator abort: from the operator console \(Escape key\)/.test(document.getElementById("latch-text").textContent)))) return;
  if (!/abort delivered at \d\d:\d\d:\d\d/.test(await text(page, "#message"))) fail("the abort's delivery: " + (await text(page, "#message")));
  await waitFor(page, "idle after the abort", () => document.body.dataset.state === "idle");
  await sleep(1500);
  await page.screenshot({ path: join(dir, "console-latched-1400.png") });
  await page.setViewport({ width: 390, height: 844 });
  await sleep(300);
  await page.screenshot({ path: join(dir, "console-latched-390.png") });
  await page.setViewport({ width: 1400, height: 900 });
  if ((await dataset(page)).latched !== "safe" || (await text(page, "#latch")) === "") fail("SAFE did not stay latched after the run ended");
  await page.click("#latch-ack");
  if ((await dataset(page)).latched !== "" || (await text(page, "#latch")) !== "") fail("Acknowledge did not clear the latch");
  // The abort is listed once (the page adds no copy of what events.jsonl records).
  await waitFor(page, "abort_request listed once", () => document.querySelectorAll('#event-list li[data-kind="abort_request"]').length === 1);
  await page.select("#event-filter", "operator");
  const groups = await page.$$eval("#event-list li", (lis) => [...new Set(lis.map((li) => li.dataset.group))]);
  if (groups.join(",") !== "operator") fail("the operator filter shows groups " + JSON.stringify(groups));
  await page.select("#event-filter", "all");
  const shot = join(dir, "console-link-1400.png");
  await page.screenshot({ path: shot });
  // A lost link is the banner's business: no unhandled error on the page ("console error: Failed to fetch").
  if ((await dataset(page)).consoleErrors !== "0") fail("the page counted errors: " + (await dataset(page)).consoleErrors);
  await page.close();  // from here no client asks the server anything: the operator link is silent

  // require_operator: the only client goes quiet mid-run; the run ends in the safe state with the
  // operator link's reason within the timeout, and telemetry.csv holds every period it ran.
  const att = await call(base, "POST", "/api/start", { campaign: "paper_adaptive", rig: "sim_attended", runs: ["adaptive"], speed: 0.5 });
  if (att.status !== 202 && att.status !== 200) return fail("start on sim_attended: " + JSON.stringify(att));
  let lastHeard = Date.now();
  for (let i = 0; i < 6; ++i) {  // a client that keeps asking keeps the link: 3 s, longer than the timeout
    const s = (await call(base, "GET", "/api/status")).json;
    lastHeard = Date.now();
    if (i > 0 && s.state !== "running") return fail(`the attended run ended while its client was heard: ${JSON.stringify(s.last ?? s)}`);
    await sleep(500);
  }
  const runsDir = join(dir, "runs");
  const attended = readdirSync(runsDir).filter((d) => d.endsWith("_paper_adaptive_adaptive")).sort().pop();
  let record = null;
  for (let i = 0; i < 300; ++i) {
    await sleep(100);
    record = JSON.parse(readFileSync(join(runsDir, attended, "run.json"), "utf8"));
    if (record.outcome !== "running") break;
  }
  if (record.outcome !== "aborted" || !/^operator link lost/.test(record.reason || "")) return fail("the unattended run: " + JSON.stringify({ outcome: record.outcome, reason: record.reason }));
  const lostEvent = readFileSync(join(runsDir, attended, "events.jsonl"), "utf8").split("\n").filter((l) => l.includes('"abort_request"')).map((l) => JSON.parse(l))[0];
  measured.push(`operator link: last request to abort ${Date.parse(lostEvent.utc) - lastHeard} ms (timeout ${kOperatorTimeoutS} s)`);
  if (record.trip?.reason !== "operator abort") fail("the unattended run's trip: " + JSON.stringify(record.trip));
  const csv = readFileSync(join(runsDir, attended, "telemetry.csv"), "utf8").split("\n").filter((l) => l && !l.startsWith("#"));
  const rows = csv.length - 1;  // the header
  const tel = record.telemetry;
  if (rows !== tel.rows_written || tel.rows_lost !== 0 || tel.rows_unwritten !== 0 || rows !== record.periods_run)
    fail(`telemetry.csv of the unattended run: ${rows} rows, run.json ${JSON.stringify(tel)}, periods_run ${record.periods_run}`);
  const lastT = Number(csv[csv.length - 1].split(",")[0]);
  if (!(lastT > kOperatorTimeoutS)) fail("the unattended run's last row at t " + lastT);
  measured.push(`unattended run: ${rows} rows = periods_run, last t ${lastT} s`);

  // Events by offset: 10 000 overruns with operator events among them, every operator event once,
  // the overruns one summary per second.
  const ev = join(runsDir, attended, "events.jsonl");
  const before = await feedAll(base, attended);
  const operatorBefore = before.events.filter((e) => e.source === "operator").length;
  let lines = "";
  for (let i = 0; i < 10_000; ++i) {
    const t = 20 + i * 0.001;
    lines += JSON.stringify({ utc: "2026-12-01T23:00:00.000Z", t_s: +t.toFixed(3), period: 20000 + i, kind: "overrun", source: "loop", late_us: 10 + (i % 97) }) + "\n";
    if (i % 1000 === 500) lines += JSON.stringify({ utc: "2026-12-01T23:00:00.000Z", t_s: +t.toFixed(3), period: 20000 + i, kind: "gap_change", source: "operator", gap_deg: i / 1000 }) + "\n";
  }
  appendFileSync(ev, lines);
  const after = await feedAll(base, attended);
  const gapChanges = after.events.filter((e) => e.kind === "gap_change" && e.t_s >= 20);
  const overruns = after.summaries.filter((s) => s.kind === "overrun" && s.t0_s >= 20);
  const overrunCount = overruns.reduce((n, s) => n + s.count, 0);
  const perSecond = new Map();
  for (const s of overruns) perSecond.set(s.t0_s, (perSecond.get(s.t0_s) || 0) + s.count);
  if (gapChanges.length !== 10 || new Set(gapChanges.map((e) => e.period)).size !== 10) fail("operator events among 10 000 overruns: " + gapChanges.length);
  if (after.events.filter((e) => e.source === "operator").length !== operatorBefore + 10) fail("operator events were lost or doubled");
  if (overrunCount !== 10_000 || perSecond.size !== 10) fail(`overrun summaries: ${overrunCount} overruns in ${perSecond.size} seconds`);
  if (overruns.some((s) => s.worst_late_us !== 106)) fail("the worst overrun of a second: " + JSON.stringify(overruns.slice(0, 2)));
  if (after.events.some((e) => e.kind === "overrun")) fail("an overrun listed one by one");
  // Only what was appended is read again: a look from the old end costs the new bytes, not the file.
  const tail = await call(base, "GET", `/api/runs/${encodeURIComponent(attended)}/events?offset=${before.size}`);
  if (tail.json.offset !== before.size) fail("the look from the old end: " + JSON.stringify(tail.json).slice(0, 200));
  measured.push(`events.jsonl ${after.size} B (${lines.length} B appended); all of it by offset: ${after.looks} looks, ${after.bytes} B answered; ` +
    `the appended part alone: ${tail.bytes} B`);
  const bad = await call(base, "GET", `/api/runs/${encodeURIComponent(attended)}/events?offset=${before.size + 3}`);
  if (bad.status !== 400 || bad.json?.field !== "offset") fail("an offset inside a line: " + JSON.stringify(bad));
  const past = await call(base, "GET", `/api/runs/${encodeURIComponent(attended)}/events?offset=99999999999`);
  if (past.status !== 400 || past.json?.field !== "offset") fail("an offset past the end: " + JSON.stringify(past));

  // The page's event fetches while a run grows: each look fetches what was appended only.
  const watcher = await browser.newPage();
  watcher.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
  await watcher.goto(base + "/", { waitUntil: "load" });
  await waitFor(watcher, "idle", () => document.body.dataset.state === "idle");
  // A page opened idle reads the last run's events first (what became of it): not the growing run's cost.
  await waitFor(watcher, "the last run's events read", () => Number(document.body.dataset.eventFetches) >= 1);
  await sleep(500);
  const readFirst = { bytes: Number((await dataset(watcher)).eventBytes), fetches: Number((await dataset(watcher)).eventFetches) };
  const grow = await call(base, "POST", "/api/start", { campaign: "paper_adaptive", rig: "sim", runs: ["adaptive"], speed: 1 });
  if (grow.status !== 202 && grow.status !== 200) return fail("start the growing run: " + JSON.stringify(grow));
  await waitFor(watcher, "running", () => document.body.dataset.state === "running");
  const samples = [];
  for (let i = 0; i < 3; ++i) {
    await sleep(4000);
    const d = await dataset(watcher);
    samples.push({ bytes: Number(d.eventBytes), fetches: Number(d.eventFetches) });
  }
  await waitFor(watcher, "the growing run ended", () => document.body.dataset.state === "idle", undefined, 60_000);
  const grown = readdirSync(runsDir).filter((d) => d.endsWith("_paper_adaptive_adaptive")).sort().pop();
  const fileBytes = readFileSync(join(runsDir, grown, "events.jsonl")).length;
  const total = Number((await dataset(watcher)).eventBytes) - readFirst.bytes;
  const looks = Number((await dataset(watcher)).eventFetches) - readFirst.fetches;
  const perLook = samples.slice(1).map((s, i) => ((s.bytes - samples[i].bytes) / Math.max(1, s.fetches - samples[i].fetches)).toFixed(0));
  measured.push(`page, 18 s run: events.jsonl ${fileBytes} B, fetched ${total} B in ${looks} looks (the last run's first: ${readFirst.bytes} B); ` +
    `bytes per look over 4 s windows ${perLook.join(", ")}`);
  // Re-downloading the file every second would fetch it about once per second of run; by offset
  // each byte is fetched once (plus each answer's JSON envelope).
  if (!(total < 2 * fileBytes + 200 * looks))
    fail(`the page fetched ${total} B of events for a ${fileBytes} B events.jsonl`);

  // Compare/Diagnose from a run default to the run's own plant: soak_random runs constant_volume.
  const soak = await call(base, "POST", "/api/start", { campaign: "soak_random", rig: "sim", runs: ["adaptive"], speed: 10 });
  if (soak.status !== 202 && soak.status !== 200) return fail("start soak_random: " + JSON.stringify(soak));
  await waitFor(watcher, "soak_random running", () => document.body.dataset.state === "running");
  await sleep(1000);
  await call(base, "POST", "/api/abort", { reason: "enough" });
  await waitFor(watcher, "soak_random's row with its plant chosen", () => {
    const row = [...document.querySelectorAll("#runs-table tbody tr")].find((tr) => /_soak_random_adaptive$/.test(tr.dataset.run));
    return row && row.querySelector("select.model") && row.querySelector("select.model").value === "constant_volume";
  }, undefined, 30_000);

  if ((await dataset(watcher)).consoleErrors !== "0") fail("the watching page counted errors: " + (await dataset(watcher)).consoleErrors);
  for (const p of problems) fail(p);
  console.log(measured.join("; ") + "; screenshot " + shot);
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(h.deadline);
  h.finish();
});
