// The console's one screen, its markers and its verdicts (issues 40 and 41), in Debian's Chromium
// against the real `hilbench serve`, on one short run (paper_adaptive's adaptive run, stopped by
// the operator after the injections, with a check set to fail):
//  - at 1400x900 the state, run time, progress, ABORT and the pressure, angle and gap plots lie
//    inside the viewport without scrolling; at 390x844 the state, run time and ABORT do; every
//    plot's y and x tick labels are distinct, every axis is labelled with a unit; screenshots of
//    both are written (HIL_SCREENSHOTS_DIR, else the temp folder) and checked not blank;
//  - a gap change and a sensor fault injected through the page appear as labelled markers on the
//    live plots ("gap 3.7 deg", "sensor stuck ...") and the fault as a shaded window;
//  - the verdict panel shows the run's checks when it ends: the failing one as FAIL with its value
//    and limit, the passing ones as pass, no cell cut off at the card's edge;
//  - the run's report marks the same events (labels drawn on its canvases), shades the fault window
//    and says in its header what happened ("gap 3.7 deg at ... s");
//  - with prefers-color-scheme: dark the page is dark.
//   node console_report_test.mjs HILBENCH_EXE SOURCE_DIR      (HIL_KEEP_SCREENSHOTS=1 keeps the temp dir)
import { mkdirSync, readdirSync, readFileSync, symlinkSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { dataset, decodePng, harness, inkOf, sleep } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const h = harness("hil-console-report-", 200);
const fail = h.fail;
const injectedGapDeg = 3.7;  // never in paper_adaptive's programme
const shotsDir = process.env.HIL_SCREENSHOTS_DIR || h.dir;

// paper_adaptive, 40 s (the test stops it once it has seen what it wants), as "console_checks",
// with one more check no run can pass.
function configs() {
  const c = join(h.dir, "configs");
  mkdirSync(join(c, "campaigns"), { recursive: true });
  for (const sub of ["plant", "rigs"]) symlinkSync(join(sourceDir, "configs", sub), join(c, sub));
  const paper = readFileSync(join(sourceDir, "configs", "campaigns", "paper_adaptive.yaml"), "utf8");
  const mine = paper.replace(/^name: paper_adaptive\b/m, "name: console_checks").replace(/^duration_s: 18\b/m, "duration_s: 40") +
    "  - name: iae_impossible\n    runs: [adaptive]\n    metric: iae_mpa_s\n    max: 0.000001\n";
  if (!mine.includes("console_checks") || !mine.includes("duration_s: 40")) throw new Error("paper_adaptive.yaml changed: name or duration_s not found");
  writeFileSync(join(c, "campaigns", "console_checks.yaml"), mine);
  return c;
}

// Where an element is, and whether it lies wholly inside the viewport (w x h) and is shown.
const boxOf = (page, sel) => page.$eval(sel, (e) => {
  const r = e.getBoundingClientRect();
  return { top: r.top, left: r.left, bottom: r.bottom, right: r.right, shown: r.width > 0 && r.height > 0 && getComputedStyle(e).visibility !== "hidden" };
});
async function insideViewport(page, w, h_, selectors, label) {
  await page.evaluate(() => window.scrollTo(0, 0));
  for (const sel of selectors) {
    const b = await boxOf(page, sel);
    if (!b.shown || b.top < 0 || b.left < 0 || b.bottom > h_ + 0.5 || b.right > w + 0.5) fail(`${label}: ${sel} not inside the ${w}x${h_} viewport: ${JSON.stringify(b)}`);
  }
}
// Each plot's tick labels (distinct, at least two per axis) and axis labels (with a unit).
async function axesReadable(page, label) {
  const axes = await page.evaluate(() => Object.fromEntries(["pressure", "angles", "gap", "observer"].map((id) => {
    const div = document.getElementById("plot-" + id);
    const texts = (sel) => [...div.querySelectorAll(sel)].map((e) => e.textContent.trim()).filter((t) => t);
    return [id, { y: texts(".dygraph-axis-label-y"), x: texts(".dygraph-axis-label-x"), xl: texts(".dygraph-xlabel"), yl: texts(".dygraph-ylabel") }];
  })));
  for (const [id, a] of Object.entries(axes)) {
    for (const k of ["x", "y"]) {
      if (a[k].length < 2 || new Set(a[k]).size !== a[k].length) fail(`${label}: plot ${id} ${k} tick labels not distinct: ${JSON.stringify(a[k])}`);
    }
    if (!/\[s\]/.test(a.xl.join(" "))) fail(`${label}: plot ${id} x axis label without its unit: ${JSON.stringify(a.xl)}`);
    if (!/\[.+\]/.test(a.yl.join(" "))) fail(`${label}: plot ${id} y axis label without its unit: ${JSON.stringify(a.yl)}`);
  }
  return axes;
}
async function screenshot(page, name) {
  const file = join(shotsDir, name);
  const buf = Buffer.from(await page.screenshot({ fullPage: false }));
  writeFileSync(file, buf);
  const png = decodePng(buf);
  const ink = inkOf(png);
  if (ink.colours < 50 || ink.inkShare < 0.05) fail(`${name} looks blank: ${ink.colours} colours, ${(100 * ink.inkShare).toFixed(1)} % ink`);
  return `${file} (${png.width}x${png.height}, ${ink.colours} colours)`;
}

const t0 = Date.now();
const phases = [];
const phase = (what) => phases.push(what + " " + ((Date.now() - t0) / 1000).toFixed(1) + " s");

async function main() {
  mkdirSync(shotsDir, { recursive: true });
  const base = await h.startServer(exe, configs());
  const browser = await h.launch();
  const problems = [];
  const page = await h.openConsole(base, "console_checks", problems);
  if (!page) return;
  await page.select("#campaign", "console_checks");
  for (const r of await page.$$eval("#runs-choice input", (b) => b.map((x) => x.value))) if (r !== "adaptive") await page.click(`#runs-choice input[value="${r}"]`);
  await page.click("#start");
  if (!(await h.waitFor(page, "running with plots drawn", () => document.body.dataset.state === "running" && Number(document.body.dataset.points) >= 200))) return;

  phase("running");
  // One screen at 1400x900.
  await sleep(300);
  await insideViewport(page, 1400, 900, ["#state", "#run-time", "#progress", "#abort", "#plot-pressure", "#plot-angles", "#plot-gap"], "1400x900");
  const wide = await axesReadable(page, "1400x900");
  const shots = [await screenshot(page, "console-1400x900.png")];

  // The phone: state, run time and ABORT in view; readable ticks.
  await page.setViewport({ width: 390, height: 844 });
  await sleep(500);
  await insideViewport(page, 390, 844, ["#state", "#run-time", "#abort"], "390x844");
  await axesReadable(page, "390x844");
  shots.push(await screenshot(page, "console-390x844.png"));
  await page.setViewport({ width: 1400, height: 900 });

  // Injections through the page: a gap change and a sensor stuck for 1 s, each confirmed.
  await page.$eval("#gap-deg", (input, v) => (input.value = String(v)), injectedGapDeg);
  await page.click("#inject-gap");
  await page.click("#confirm-yes");
  await page.select("#sensor-mode", "stuck");
  await page.$eval("#sensor-duration", (input) => (input.value = "1"));
  await page.click("#inject-sensor");
  await page.click("#confirm-yes");
  const gapLabel = "gap " + injectedGapDeg + " deg";
  await h.waitFor(page, "the gap change and the sensor fault marked on the live pressure plot", (want) => {
    const m = JSON.parse(document.getElementById("plot-pressure").dataset.markers || "[]");
    return m.includes(want) && m.some((l) => l.startsWith("sensor stuck")) && Number(document.getElementById("plot-pressure").dataset.windows) >= 1;
  }, gapLabel);
  const liveMarks = await page.$eval("#plot-pressure", (d) => ({ markers: d.dataset.markers, windows: d.dataset.windows }));

  // Stop (the run ends "stopped" and is judged on what it ran); its verdicts show at its end:
  // the impossible check fails with value and limit.
  phase("marked");
  await page.click("#stop");
  if (!(await h.waitFor(page, "the run's verdicts shown", () => Number(document.body.dataset.verdictsFailed) >= 1, undefined, 60_000))) return;
  const verdicts = await page.$$eval("#verdict-list tr", (rows) => rows.map((tr) => ({ check: tr.dataset.check, verdict: tr.dataset.verdict,
    cells: [...tr.children].map((td) => td.textContent) })));
  const bad = verdicts.find((v) => v.check === "iae_impossible");
  if (!bad || bad.verdict !== "fail" || bad.cells[1] !== "FAIL" || !/^\d/.test(bad.cells[2]) || bad.cells[3] !== "≤ 0.000001")
    fail("the failing check as shown: " + JSON.stringify(bad));
  if (!verdicts.some((v) => v.verdict === "pass" && /^\d/.test(v.cells[2]))) fail("no passing check shown: " + JSON.stringify(verdicts));
  const summary = await page.$eval("#verdict-summary", (e) => e.textContent);
  if (!/^console_checks: [1-9]\d* passed, [1-9]\d* failed/.test(summary)) fail("verdict summary: " + summary);
  // Every value and limit is readable where it stands (at 1400 px the checks are a third of the
  // screen): the table is not wider than its card, so no cell is cut off at the edge ("≤ 0" for "≤ 0.2").
  const clipped = await page.$eval("#verdict-table", (t) => {
    const wrap = t.parentElement.getBoundingClientRect();
    return [...t.querySelectorAll("td")].filter((td) => td.getBoundingClientRect().right > wrap.right + 1).map((td) => td.textContent);
  });
  if (clipped.length) fail("checks cut off at the card's edge: " + JSON.stringify(clipped));

  phase("judged");
  // The run's report: the same marks, the fault window shaded, the header saying what happened.
  if (!(await h.waitFor(page, "the run's report link", () => !!document.querySelector("#runs-table tbody tr a.report"), undefined, 30_000))) return;
  const href = await page.$eval("#runs-table tbody tr a.report", (a) => a.href);
  const report = await browser.newPage();
  report.on("pageerror", (e) => problems.push(`report page error: ${e.message}`));
  await report.setViewport({ width: 1400, height: 900 });
  const res = await report.goto(href, { waitUntil: "load", timeout: 60_000 });
  if (res.status() !== 200) return fail("report answered " + res.status());
  await h.waitFor(report, "the report's plots drawn", () => Number(document.body.dataset.plots) > 0 && document.querySelectorAll("canvas[data-markers]").length > 0);
  const drawn = await report.$$eval("canvas[data-markers]", (cs) => cs.map((c) => JSON.parse(c.dataset.markers)));
  const withGap = drawn.filter((m) => m.includes(gapLabel)).length;
  const withFault = drawn.filter((m) => m.some((l) => l.startsWith("sensor stuck"))).length;
  if (withGap < 4 || withFault < 4) fail(`report: ${withGap} plots mark the gap change, ${withFault} the sensor fault (want every time plot): ${JSON.stringify(drawn)}`);
  const bands = await report.$$eval(".hil-lg.static", (s) => s.map((e) => e.textContent));
  if (!bands.some((t) => t.startsWith("sensor stuck"))) fail("report: no shaded sensor-fault window in a legend: " + JSON.stringify(bands));
  const header = await report.$$eval("p", (ps) => ps.map((p) => p.textContent).find((t) => t.startsWith("What happened in adaptive")) || "");
  if (!new RegExp("gap " + injectedGapDeg + " deg at \\d+\\.\\d{3} s").test(header) || !/sensor stuck .* \d+\.\d{3}-\d+\.\d{3} s/.test(header))
    fail("report header: " + JSON.stringify(header));
  await report.close();
  phase("report checked");

  // Dark when the browser asks for it.
  await page.emulateMediaFeatures([{ name: "prefers-color-scheme", value: "dark" }]);
  await sleep(200);
  const bg = await page.evaluate(() => getComputedStyle(document.body).backgroundColor);
  const rgb = (bg.match(/\d+/g) || []).map(Number);
  if (!(rgb.length >= 3 && rgb[0] + rgb[1] + rgb[2] < 150)) fail("dark scheme: body background " + bg);
  shots.push(await screenshot(page, "console-1400x900-dark.png"));

  const ds = await dataset(page);
  if (ds.consoleErrors !== "0") fail("the console counted errors: " + ds.consoleErrors);
  for (const p of problems) fail(p);
  console.log(`live marks ${JSON.stringify(liveMarks)}; report marks ${withGap}/${withFault} plots; header "${header}"; verdicts ${summary}; ` +
    `pressure y ticks at 1400: ${JSON.stringify(wide.pressure.y)}; screenshots ${shots.join(", ")}; times (printed, not asserted): ${phases.join(", ")}`);
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(h.deadline);
  h.finish();
});
