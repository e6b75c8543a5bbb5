// A long run's report at full resolution on zoom (issue 40, point 7), in Debian's Chromium against
// the real `hilbench serve`, on a 30 s 1 kHz run recorded by `hilbench run` on the sim rig (the
// campaign runner without the API, 100x faster than real time: a real run folder in a second):
//  - served (GET /api/runs/ID/report.html), every time plot says it is thinned (min and max per
//    bucket) and what a zoom will show;
//  - zoomed to 1 s, every plot of the linked group draws every row of telemetry.csv in the window
//    (counted against the file read here, p_meas_mpa's values compared one by one) and the
//    thinned note is gone; zoomed out again, the overview and its note are back;
//  - the same report.html opened from disk says that every sample needs the server, zoomed too;
//  - GET /api/runs/ID/telemetry refuses a column that is no telemetry column, a missing to_s and a
//    range holding more rows than max_rows, each naming the field.
//   node report_zoom_test.mjs HILBENCH_EXE SOURCE_DIR
import { spawnSync } from "node:child_process";
import { mkdirSync, readdirSync, readFileSync, symlinkSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { harness } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const h = harness("hil-report-zoom-", 120);
const fail = h.fail;
const zoom = [15.2, 16.2];  // s: 1 s of the 30 s run

// paper_adaptive at 30 s as "zoom30"; plant and rigs from the tree.
function configs() {
  const c = join(h.dir, "configs");
  mkdirSync(join(c, "campaigns"), { recursive: true });
  for (const sub of ["plant", "rigs"]) symlinkSync(join(sourceDir, "configs", sub), join(c, sub));
  const paper = readFileSync(join(sourceDir, "configs", "campaigns", "paper_adaptive.yaml"), "utf8");
  const mine = paper.replace(/^name: paper_adaptive\b/m, "name: zoom30").replace(/^duration_s: 18\b/m, "duration_s: 30");
  if (!mine.includes("name: zoom30") || !mine.includes("duration_s: 30")) throw new Error("paper_adaptive.yaml changed: name or duration_s not found");
  writeFileSync(join(c, "campaigns", "zoom30.yaml"), mine);
  return c;
}

// The rows of telemetry.csv with t_s in [a, b]: their times and p_meas_mpa, read here, not through the server.
function csvWindow(file, a, b) {
  const lines = readFileSync(file, "utf8").split("\n").filter((l) => l && !l.startsWith("#"));
  const head = lines[0].split(","), pi = head.indexOf("p_meas_mpa");
  const rows = lines.slice(1).map((l) => l.split(",")).filter((c) => Number(c[0]) >= a && Number(c[0]) <= b);
  return { t: rows.map((c) => Number(c[0])), p: rows.map((c) => Number(c[pi])), total: lines.length - 1 };
}

// Every time plot's note, its class, and the rows its graph holds inside the shown x range (and
// the measured pressure's value at each, where the plot has it).
const plotsState = (page) => page.evaluate(() => window.hilReport.charts.filter((c) => c.group === "t").map((c) => {
  const g = c.graph, [a, b] = g.xAxisRange(), res = c.fig.querySelector(".hil-res");
  const col = c.spec.series.findIndex((s) => s.src && s.src.col === "p_meas_mpa");
  const t = [], p = [];
  for (let i = 0; i < g.numRows(); ++i) {
    const x = g.getValue(i, 0);
    if (x < a || x > b) continue;
    t.push(x);
    if (col >= 0) p.push(g.getValue(i, col + 1));
  }
  return { title: c.fig.querySelector("figcaption").textContent, cls: res ? res.className : "", note: res ? res.textContent : "",
    shown: !!res && res.offsetParent !== null, t, p, zoomed: g.isZoomed("x") };
}));

async function zoomTo(page, range) {
  await page.evaluate((r) => window.hilReport.charts.find((c) => c.group === "t").graph.updateOptions({ dateWindow: r }), range);
}

const t0 = Date.now(), phases = [];
const phase = (name) => phases.push(`${name} ${((Date.now() - t0) / 1000).toFixed(1)} s`);
try {
  const runs = join(h.dir, "runs");
  const c = configs();
  // Exit status 3: a check of paper_adaptive's failed at this length, which is not what is tested.
  const rec = spawnSync(exe, ["run", join(c, "campaigns", "zoom30.yaml"), "--rig", "sim", "--runs", "adaptive", "--speed", "100",
    "--out", runs, "--configs", c, "--no-mlock", "--quiet"], { stdio: ["ignore", "ignore", "pipe"], encoding: "utf8" });
  if (rec.status !== 0 && rec.status !== 3) throw new Error("hilbench run: exit " + rec.status + ": " + rec.stderr);
  const id = readdirSync(runs).find((d) => d.includes("adaptive"));
  if (!id) throw new Error("hilbench run left no run folder in " + runs + ": " + readdirSync(runs));
  const csv = join(runs, id, "telemetry.csv");
  const want = csvWindow(csv, ...zoom);
  if (want.total < 29000 || want.t.length < 900) throw new Error(`telemetry.csv has ${want.total} rows, ${want.t.length} in the zoom`);

  phase("recorded");
  const base = await h.startServer(exe, c);
  phase("served");
  const api = (path) => fetch(base + path).then(async (r) => ({ status: r.status, body: await r.json().catch(() => ({})) }));
  for (const [q, field] of [["from_s=1&to_s=2&columns=p_meas_mpa,p_bogus", "columns"], ["from_s=1&columns=p_meas_mpa", "to_s"],
    ["from_s=0&to_s=30&columns=p_meas_mpa&max_rows=100", "to_s"], ["from_s=2&to_s=1&columns=p_meas_mpa", "to_s"]]) {
    const r = await api(`/api/runs/${id}/telemetry?${q}`);
    if (r.status !== 400 || r.body.field !== field) fail(`telemetry?${q}: want 400 naming '${field}', got ${r.status} ${JSON.stringify(r.body)}`);
  }
  const direct = await api(`/api/runs/${id}/telemetry?from_s=${zoom[0]}&to_s=${zoom[1]}&columns=p_meas_mpa,gap_true_deg`);
  if (direct.status !== 200 || direct.body.rows !== want.t.length || direct.body.columns.p_meas_mpa.some((v, k) => v !== want.p[k]))
    fail(`telemetry range: want the file's ${want.t.length} rows, got ${direct.status} ${direct.body.rows}`);

  phase("endpoint checked");
  const browser = await h.launch();
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 900 });
  const errors = [];
  page.on("pageerror", (e) => errors.push(String(e)));
  await page.goto(`${base}/api/runs/${id}/report.html?wait=1`, { waitUntil: "load" });
  phase("report opened");
  const before = await plotsState(page);
  if (before.length < 4) fail(`the report has ${before.length} time plots`);
  for (const p of before) {
    if (!p.shown || !p.cls.includes("hil-thin") || !/^thinned: min and max per .* zoom in for every sample$/.test(p.note))
      fail(`${p.title}: overview note ${JSON.stringify(p)}`);
  }
  await zoomTo(page, zoom);
  await h.waitFor(page, "every time plot draws every sample of the zoom",
    () => window.hilReport.charts.filter((c) => c.group === "t").every((c) => c.fig.querySelector(".hil-res.hil-full")), null, 20_000);
  for (const p of await plotsState(page)) {
    if (p.t.length !== want.t.length || p.t.some((t, k) => Math.abs(t - want.t[k]) > 1e-9))
      fail(`${p.title}: ${p.t.length} rows drawn in the zoom, telemetry.csv has ${want.t.length}`);
    // A value inside a run of equal values is left out of the table (the same line, connected over).
    const same = (k) => want.p[k - 1] === want.p[k] && want.p[k + 1] === want.p[k];
    if (p.p.length && p.p.some((v, k) => (v === null ? !same(k) : v !== want.p[k]))) fail(`${p.title}: p_meas_mpa drawn is not the file's`);
    if (p.cls.includes("hil-thin") || !/^every sample: [\d,]+ rows in view/.test(p.note)) fail(`${p.title}: zoomed note ${p.cls} "${p.note}"`);
  }
  phase("zoomed");
  console.log(`served: ${before.length} time plots thinned, each drew all ${want.t.length} rows of ${zoom.join("-")} s`);
  await zoomTo(page, null);
  await h.waitFor(page, "zoomed out: the overview and its note again",
    () => window.hilReport.charts.filter((c) => c.group === "t").every((c) => c.fig.querySelector(".hil-res.hil-thin") && !c.detail), null, 10_000);

  // The file on disk, without the server.
  const local = await browser.newPage();
  local.on("pageerror", (e) => errors.push(String(e)));
  await local.goto("file://" + join(runs, id, "report.html"), { waitUntil: "load" });
  await zoomTo(local, zoom);
  await new Promise((r) => setTimeout(r, 400));
  for (const p of await plotsState(local)) {
    if (!p.cls.includes("hil-thin") || !p.note.includes("every sample on zoom needs the server: hilbench serve") || p.t.length >= want.t.length)
      fail(`${p.title} from disk: ${p.cls} "${p.note}", ${p.t.length} rows in the zoom`);
  }
  phase("from disk");
  console.log("at: " + phases.join(", "));
  if (errors.length) fail("page errors: " + errors.join("; "));
} catch (e) {
  fail(e.stack || String(e));
}
await h.finish();
