// Markers in every report (issue 40, point 4): the events of a served run (an operator's gap change
// and a sensor fault, injected through the API into paper_adaptive's adaptive run on the sim rig)
// are labelled markers on the time plots of the Compare and the Diagnose analyses of that run, in
// the run report's words ("gap 3.7 deg", "sensor stuck ..."), the fault's window shaded (a legend
// entry of its own), and each says what happened and when; the run's own report marks the same.
// In Debian's Chromium against the real `hilbench serve`.
//   node report_marks_test.mjs HILBENCH_EXE SOURCE_DIR
import { harness, sleep } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const h = harness("hil-report-marks-", 280);
const fail = h.fail;
const injectedGapDeg = 3.7;  // never in paper_adaptive's programme

async function call(base, method, path, payload) {
  const res = await fetch(base + path, { method, headers: payload ? { "Content-Type": "application/json" } : {},
    body: payload ? JSON.stringify(payload) : undefined });
  const text = await res.text();
  let json = null;
  try {
    json = JSON.parse(text);
  } catch (e) {
    json = null;
  }
  return { status: res.status, json, text };
}
// Polls `get` until `ok(value)`; the last value (and a failure naming `what`) when it never is.
async function until(what, get, ok, timeoutMs) {
  const end = Date.now() + timeoutMs;
  let v = await get();
  while (!ok(v) && Date.now() < end) {
    await sleep(200);
    v = await get();
  }
  if (!ok(v)) fail(`${what} (within ${timeoutMs / 1000} s): ${JSON.stringify(v).slice(0, 400)}`);
  return v;
}

// The labels drawn on each plot's canvas, the band legends and the paragraphs of a report page.
async function reportMarks(browser, url, problems) {
  const page = await browser.newPage();
  page.on("pageerror", (e) => problems.push(`${url}: page error: ${e.message}`));
  await page.setViewport({ width: 1400, height: 900 });
  const res = await page.goto(url, { waitUntil: "load", timeout: 60_000 });
  if (res.status() !== 200) throw new Error(url + " answered " + res.status());
  // Every plot drawn, also those below the fold (report.js draws them after the ones in view).
  await page.waitForFunction(() => Number(document.body.dataset.plots) > 0, { timeout: 60_000, polling: 50 });
  const got = await page.evaluate(() => ({
    errors: Number(document.body.dataset.plotErrors),
    plots: [...document.querySelectorAll("figure.hil-fig")].filter((f) => /time \[s\]/.test(f.querySelector("script.hil-data").textContent))
      .map((f) => ({ title: f.querySelector("figcaption").textContent,
        markers: JSON.parse((f.querySelector("canvas[data-markers]") || { dataset: {} }).dataset.markers || "null") })),
    bands: [...document.querySelectorAll(".hil-lg.static")].map((e) => e.textContent),
    paragraphs: [...document.querySelectorAll("p")].map((p) => p.textContent),
  }));
  await page.close();
  return got;
}

async function main() {
  const base = await h.startServer(exe, sourceDir + "/configs");
  const browser = await h.launch();
  const problems = [];
  const started = await call(base, "POST", "/api/start", { campaign: "paper_adaptive", rig: "sim", runs: ["adaptive"], speed: 2 });
  if (started.status !== 202 && started.status !== 200) return fail("start: " + started.status + " " + started.text);
  await until("running past 3 s", () => call(base, "GET", "/api/status"),
    (s) => s.json && s.json.state === "running" && s.json.progress && s.json.progress.t_s > 3, 60_000);
  const gap = await call(base, "POST", "/api/inject/gap", { gap_deg: injectedGapDeg });
  if (gap.status !== 200 && gap.status !== 202) return fail("inject gap: " + gap.status + " " + gap.text);
  await sleep(500);
  const sensor = await call(base, "POST", "/api/inject/sensor", { mode: "stuck", duration_s: 1 });
  if (sensor.status !== 200 && sensor.status !== 202) return fail("inject sensor: " + sensor.status + " " + sensor.text);
  await until("the run ended", () => call(base, "GET", "/api/status"), (s) => s.json && s.json.state === "idle", 60_000);
  const run = (await call(base, "GET", "/api/runs")).json.runs.find((r) => (r.id || "").includes("adaptive"));
  if (!run) return fail("no adaptive run listed");

  // Compare and Diagnose of the run, against its own plant, each queued on the job worker.
  const one = (j) => (j && j.analysis) || j || {};  // POST answers {analysis}, GET the analysis itself
  const checks = [];
  for (const kind of ["compare", "diagnose"]) {
    const asked = await call(base, "POST", `/api/runs/${run.id}/analyses`, { kind, model: run.plant || "nominal" });
    if (asked.status !== 202 && asked.status !== 200) return fail(`${kind}: ${asked.status} ${asked.text}`);
    const aid = one(asked.json).id;
    const done = await until(`the ${kind} analysis done`, () => call(base, "GET", `/api/runs/${run.id}/analyses/${aid}`),
      (a) => one(a.json).state === "done" || one(a.json).state === "failed", 150_000);
    if (one(done.json).state !== "done") return fail(`${kind}: ${JSON.stringify(done.json)}`);
    checks.push([kind, `${base}/api/runs/${run.id}/analyses/${aid}/report.html`, "What happened in the run: "]);
  }

  const gapLabel = `gap ${injectedGapDeg} deg`;
  checks.push(["run report", `${base}/api/runs/${run.id}/report.html?wait=1`, "What happened in adaptive"]);
  const seen = [];
  for (const [name, url, header] of checks) {
    const r = await reportMarks(browser, url, problems);
    if (r.errors) fail(`${name}: ${r.errors} plots could not be drawn`);
    // Every plot against time marks both (compare: pressure, residual, drive angle, residual per
    // window; diagnose also its before-and-after pressure and residual; at least 3 in each report).
    const withGap = r.plots.filter((p) => p.markers && p.markers.includes(gapLabel));
    const withFault = r.plots.filter((p) => p.markers && p.markers.some((m) => /^sensor stuck/.test(m)));
    if (r.plots.length < 3 || withGap.length < r.plots.length || withFault.length < r.plots.length)
      fail(`${name}: of ${r.plots.length} time plots ${withGap.length} mark "${gapLabel}", ${withFault.length} the sensor fault: ${JSON.stringify(r.plots)}`);
    if (!r.bands.some((b) => /^sensor stuck/.test(b))) fail(`${name}: no shaded sensor-fault window in a legend: ${JSON.stringify(r.bands)}`);
    const said = r.paragraphs.find((t) => t.startsWith(header)) || "";
    if (!new RegExp(`${gapLabel} at \\d+\\.\\d{3} s`).test(said) || !/sensor stuck[^;]* \d+\.\d{3}-\d+\.\d{3} s/.test(said))
      fail(`${name}: the header does not say what happened: ${JSON.stringify(said)}`);
    seen.push(`${name}: ${withGap.length} of ${r.plots.length} time plots mark the gap change, "${said}"`);
  }
  for (const p of problems) fail(p);
  console.log(seen.join("; "));
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(h.deadline);
  h.finish();
});
