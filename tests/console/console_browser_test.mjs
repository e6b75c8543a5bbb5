// The operator console of the real `hilbench serve`, driven in Debian's Chromium (puppeteer-core):
// choose paper_adaptive's adaptive run on the sim rig and click Start; the plots grow (the page's
// redraw counter and held rows rise); a gap change injected through the page (with its confirm
// step) shows in the events list and as the true gap in the gap plot's data; Abort ends the run
// "aborted" in the runs list; the run's report link opens the paper-style report with its figures;
// Compare against the nominal model, clicked in the run's row, runs to done and its report opens;
// the gap plot's y tick labels are distinct numbers whatever the range; a rig driving a real motor
// without the following-error interlock is warned about in red before Start.
// No console error or page error on either page; screenshots at 1400 and 390 px are not blank.
//   node console_browser_test.mjs HILBENCH_EXE SOURCE_DIR      (HIL_KEEP_SCREENSHOTS=1 keeps the temp dir)
import { mkdirSync, readdirSync, readFileSync, symlinkSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { dataset, decodePng, harness, inkOf, sleep } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const injectedGapDeg = 3.7;  // paper_adaptive's programme never has this gap: a row with it is the injection
const h = harness("hil-console-", 240);
const { dir, fail, waitFor } = h;

async function screenshotChecked(page, width, name) {
  await page.setViewport({ width, height: 900 });
  await sleep(400);  // the redraw timer and the layout follow the new width
  const file = join(dir, name);
  const buf = Buffer.from(await page.screenshot({ fullPage: true }));
  writeFileSync(file, buf);
  const png = decodePng(buf);
  const ink = inkOf(png);
  if (png.width !== width) fail(`${name}: ${png.width} px wide, not ${width}`);
  if (ink.colours < 50 || ink.inkShare < 0.05) fail(`${name} looks blank: ${ink.colours} colours, ${(100 * ink.inkShare).toFixed(1)} % ink`);
  return `${name} ${png.width}x${png.height}: ${ink.colours} colours, ${(100 * ink.inkShare).toFixed(1)} % ink`;
}

// The shipped configs, plus a rig the server must warn about: the CAN rig without its
// following-error interlock. The rigs are copies with the drivers' files named absolutely.
function configsWithBareRig() {
  const configs = join(dir, "configs");
  mkdirSync(join(configs, "rigs"), { recursive: true });
  symlinkSync(join(sourceDir, "configs", "plant"), join(configs, "plant"));
  // paper_adaptive as shipped but 60 s long instead of 18: the test aborts it after watching,
  // zooming and injecting, which on a loaded machine took longer than 18 s (the run had ended).
  mkdirSync(join(configs, "campaigns"));
  const paper = readFileSync(join(sourceDir, "configs", "campaigns", "paper_adaptive.yaml"), "utf8");
  const longer = paper.replace(/^duration_s: 18\b/m, "duration_s: 60");
  if (longer === paper) throw new Error("paper_adaptive.yaml's 'duration_s: 18' was not found");
  writeFileSync(join(configs, "campaigns", "paper_adaptive.yaml"), longer);
  const rig = (name) => readFileSync(join(sourceDir, "configs", "rigs", name), "utf8").replaceAll("../../drivers/", join(sourceDir, "drivers") + "/");
  for (const name of readdirSync(join(sourceDir, "configs", "rigs"))) writeFileSync(join(configs, "rigs", name), rig(name));
  const bare = rig("can.yaml").replace(/^ *following_error:.*$/m, "");
  if (bare.includes("following_error:")) throw new Error("can.yaml's following_error line was not removed");
  writeFileSync(join(configs, "rigs", "bare_can.yaml"), bare);
  return configs;
}

async function main() {
  const base = await h.startServer(exe, configsWithBareRig());
  const browser = await h.launch();
  const problems = [];
  const watch = (page, label) => {
    page.on("console", (m) => { if (m.type() === "error") problems.push(`${label} console error: ${m.text()}`); });
    page.on("pageerror", (e) => problems.push(`${label} page error: ${e.message}`));
    page.on("response", (r) => { if (r.status() >= 400) problems.push(`${label}: ${r.status()} for ${r.url()}`); });
  };
  const page = await browser.newPage();
  watch(page, "console");
  await page.setViewport({ width: 1400, height: 900 });
  const loaded = await page.goto(base + "/", { waitUntil: "load" });
  if (loaded.status() !== 200) return fail("GET / answered " + loaded.status());

  // Choose paper_adaptive, only its adaptive run, on the sim rig; start by clicking.
  if (!(await waitFor(page, "campaigns listed", () => [...document.querySelectorAll("#campaign option")].some((o) => o.value === "paper_adaptive")))) return;
  await page.select("#campaign", "paper_adaptive");
  // The rig's interlock shows before Start; a real drive without the following-error interlock
  // is marked in the list and warned about in red.
  const rigAbout = async (name) => {
    await page.select("#rig", name);
    return page.evaluate(() => ({ text: document.getElementById("rig-about").textContent, bad: document.querySelector("#rig-about .bad") !== null,
      option: document.querySelector("#rig option:checked").textContent }));
  };
  const can = await rigAbout("can");
  if (!can.text.includes("following-error interlock 3 deg for 100 ms") || can.bad) fail("the can rig as shown: " + JSON.stringify(can));
  const bare = await rigAbout("bare_can");
  if (!bare.bad || !bare.text.includes("WARNING") || !bare.text.includes("without safety.following_error") ||
      !bare.option.includes("no following-error interlock")) fail("the rig without following_error as shown: " + JSON.stringify(bare));
  const sim = await rigAbout("sim");
  if (sim.bad || sim.text.includes("WARNING")) fail("the sim rig as shown: " + JSON.stringify(sim));
  const runs = await page.$$eval("#runs-choice input", (boxes) => boxes.map((b) => b.value));
  if (!runs.includes("adaptive")) return fail("paper_adaptive's runs in the page: " + JSON.stringify(runs));
  for (const r of runs) if (r !== "adaptive") await page.click(`#runs-choice input[value="${r}"]`);
  await page.click("#start");
  if (!(await waitFor(page, "running with plots drawn", () => document.body.dataset.state === "running" && Number(document.body.dataset.framesRendered) >= 5 && Number(document.body.dataset.points) >= 30))) return;
  const first = await dataset(page);
  await sleep(1500);
  const second = await dataset(page);
  if (!(Number(second.framesRendered) > Number(first.framesRendered))) fail(`frames did not grow: ${first.framesRendered} then ${second.framesRendered}`);
  if (!(Number(second.points) > Number(first.points))) fail(`points did not grow: ${first.points} then ${second.points}`);
  const plotted = await page.evaluate(() => Object.keys(window.hilConsole.plots).sort().join(","));
  if (plotted !== "angles,gap,observer,pressure") fail("plots: " + plotted);

  // Zoom by dragging across the pressure plot: every plot shows that range, and they keep
  // streaming in it; Follow goes back to the newest data.
  const box = await (await page.$("#plot-pressure canvas")).boundingBox();
  await page.mouse.move(box.x + box.width * 0.3, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.6, box.y + box.height / 2, { steps: 8 });
  await page.mouse.up();
  const ranges = () => page.evaluate(() => ({ mode: window.hilConsole.view.mode, frames: Number(document.body.dataset.framesRendered),
    ranges: Object.fromEntries(Object.entries(window.hilConsole.plots).map(([k, g]) => [k, g.xAxisRange()])) }));
  const zoomed = await ranges();
  await sleep(800);
  const later = await ranges();
  const r0 = zoomed.ranges.pressure;
  if (zoomed.mode !== "fixed") fail("a drag across the plot did not zoom: mode " + zoomed.mode);
  for (const [k, r] of Object.entries(later.ranges)) {
    if (Math.abs(r[0] - r0[0]) > 1e-9 || Math.abs(r[1] - r0[1]) > 1e-9) fail(`plot ${k} shows ${r}, the zoomed pressure plot ${r0}`);
  }
  if (!(later.frames > zoomed.frames)) fail("the plots stopped redrawing while zoomed");
  await page.click("#follow");
  await sleep(300);
  const followed = await ranges();
  if (followed.mode !== "follow" || !(followed.ranges.pressure[1] > r0[1])) fail("Follow did not return to the newest data: " + JSON.stringify(followed));

  // What the API refuses is shown with its reason: a gap out of range.
  await page.$eval("#gap-deg", (input) => (input.value = "20"));
  await page.click("#inject-gap");
  await page.click("#confirm-yes");
  await waitFor(page, "the refusal shown with its reason", () => /refused \(400\).*'gap_deg' 20 deg is outside 0\.\.10 deg/.test(document.getElementById("message").textContent));
  const expectedRefusal = (p) => /inject\/gap/.test(p) && /400/.test(p) || /status of 400/.test(p);

  // The true gap in the gap plot's own data, before and after the injection.
  const gapTrueSeen = (want) => page.evaluate((want) => {
    const g = window.hilConsole.plots.gap;
    const col = g.getLabels().indexOf("true gap");
    for (let i = 0; i < g.numRows(); ++i) if (Math.abs(g.getValue(i, col) - want) < 1e-6) return true;
    return false;
  }, want);
  if (await gapTrueSeen(injectedGapDeg)) fail(`the gap plot shows a true gap of ${injectedGapDeg} deg before it was injected`);

  // A gap change through the page: the confirm step first, nothing sent before it.
  await page.$eval("#gap-deg", (input, v) => (input.value = String(v)), injectedGapDeg);
  await page.click("#inject-gap");
  const confirmText = await page.$eval("#confirm", (c) => (c.hidden ? "" : c.textContent));
  if (!confirmText.includes(String(injectedGapDeg))) fail("no confirm step naming the gap: " + JSON.stringify(confirmText));
  await sleep(300);
  if (await page.$('#event-list li[data-kind="gap_change"]')) fail("a gap change was recorded before it was confirmed");
  await page.click("#confirm-yes");
  await waitFor(page, "gap_change in the events list", (want) => [...document.querySelectorAll('#event-list li[data-kind="gap_change"]')].some((li) => li.textContent.includes("gap " + want + " deg")), injectedGapDeg);
  await waitFor(page, "the injected true gap in the gap plot", (want) => {
    const g = window.hilConsole.plots.gap;
    const col = g.getLabels().indexOf("true gap");
    for (let i = 0; i < g.numRows(); ++i) if (Math.abs(g.getValue(i, col) - want) < 1e-6) return true;
    return false;
  }, injectedGapDeg);

  // Abort: one click on the header button, which stays on screen.
  const abortBox = await page.$eval("#abort", (b) => { const r = b.getBoundingClientRect(); return { top: r.top, visible: r.width > 0 && r.height > 0 }; });
  if (!abortBox.visible || abortBox.top < 0 || abortBox.top > 200) fail("abort button not in view: " + JSON.stringify(abortBox));
  await page.evaluate(() => window.scrollTo(0, document.body.scrollHeight));
  await sleep(100);
  const abortScrolled = await page.$eval("#abort", (b) => b.getBoundingClientRect().top);
  if (abortScrolled < 0 || abortScrolled > 200) fail("abort button scrolled out of view: top " + abortScrolled);
  // The run lasts 60 s: everything above must fit in it, or the abort below finds nothing to abort.
  const before = await dataset(page);
  if (before.state !== "running") return fail("the run ended before the abort (a very slow machine?): state " + before.state);
  await page.click("#abort");
  // The plots keep the aborted run's data: the screenshots show them.
  const shots = [await screenshotChecked(page, 1400, "console-1400.png"), await screenshotChecked(page, 390, "console-390.png")];
  await page.setViewport({ width: 1400, height: 900 });
  if (!(await waitFor(page, "the run aborted in the runs list", () => [...document.querySelectorAll("#runs-table tbody tr")].some((tr) => tr.querySelector(".outcome")?.textContent === "aborted" && tr.querySelector("a.report")), undefined, 30_000))) return;
  const run = await page.$eval("#runs-table tbody tr", (tr) => ({ id: tr.dataset.run, outcome: tr.querySelector(".outcome").textContent, reason: tr.children[3].textContent, report: tr.querySelector("a.report")?.href }));
  if (!/_paper_adaptive_adaptive$/.test(run.id)) fail("newest run: " + JSON.stringify(run));
  if (!run.reason.includes("operator abort")) fail("reason: " + JSON.stringify(run));

  // The run's report, as the link opens it.
  const reportPage = await browser.newPage();
  watch(reportPage, "report");
  const res = await reportPage.goto(run.report, { waitUntil: "load", timeout: 60_000 });
  if (res.status() !== 200) fail("report answered " + res.status());
  if (!/text\/html/.test(res.headers()["content-type"] || "")) fail("report content-type " + res.headers()["content-type"]);
  const figures = await reportPage.$$eval("figure.hil-fig", (f) => f.length);
  const title = await reportPage.title();
  if (figures < 3) fail(`the report has ${figures} figures`);

  // Compare the aborted run against the nominal plant model by clicking; its state is shown
  // live, and once done its report opens from the link.
  await page.bringToFront();  // a background tab gets no animation frames: clicks in it never finish
  const row = `#runs-table tr[data-run="${run.id}"]`;
  if (!(await waitFor(page, "the plant models in the run's row", (row) => [...document.querySelectorAll(row + " select.model option")].some((o) => o.value === "nominal"), row))) return;
  await page.select(row + " select.model", "nominal");
  await page.click(row + ' button.analyse[data-kind="compare"]');
  if (!(await waitFor(page, "the compare analysis done", (row) => !!document.querySelector(row + ' ul.analyses li[data-kind="compare"][data-state="done"] a.analysis-report'), row, 90_000))) return;
  const analysis = await page.$eval(row + ' ul.analyses li[data-kind="compare"]', (li) => ({ text: li.textContent, href: li.querySelector("a.analysis-report").href }));
  if (!/compare vs nominal: fit -?\d+(\.\d)? % \(noise floor \d+(\.\d)? %\)/.test(analysis.text)) fail("the analysis as shown: " + JSON.stringify(analysis));
  const analysisPage = await browser.newPage();
  watch(analysisPage, "analysis report");
  const ares = await analysisPage.goto(analysis.href, { waitUntil: "load", timeout: 60_000 });
  if (ares.status() !== 200) fail("the analysis report answered " + ares.status());
  const analysisFigures = await analysisPage.$$eval("figure.hil-fig", (f) => f.length);
  if (analysisFigures < 1) fail(`the analysis report has ${analysisFigures} figures`);
  if (!(await analysisPage.content()).includes("nominal.yaml")) fail("the analysis report does not name the model");

  await page.bringToFront();
  // The gap plot's y ticks print distinct values with the decimals their spacing needs, also
  // when the axis spans a tenth of a degree (dygraphs' default printed "1" and "1").
  const tickSets = [];
  for (const range of [null, [0.98, 1.02], [0.9, 1.3], [0, 4]]) {
    const labels = await page.evaluate(async (range) => {
      const g = window.hilConsole.plots.gap;
      g.updateOptions({ valueRange: range });
      await new Promise((r) => requestAnimationFrame(r));
      return [...document.querySelectorAll("#plot-gap .dygraph-axis-label-y")].map((e) => e.textContent.trim()).filter((t) => t);
    }, range);
    tickSets.push(labels);
    if (labels.length < 3) fail(`gap plot, y range ${JSON.stringify(range)}: ${labels.length} tick labels ${JSON.stringify(labels)}`);
    if (new Set(labels).size !== labels.length) fail(`gap plot, y range ${JSON.stringify(range)}: tick labels repeat: ${JSON.stringify(labels)}`);
    const values = labels.map(Number);
    if (values.some((v) => !isFinite(v))) fail(`gap plot tick labels not numbers: ${JSON.stringify(labels)}`);
  }
  await page.evaluate(() => window.hilConsole.plots.gap.updateOptions({ valueRange: null }));
  await sleep(500);

  const ds = await dataset(page);
  if (ds.consoleErrors !== "0") fail("the console counted errors: " + ds.consoleErrors);
  // The one refusal provoked above shows in the browser's log as a failed load: nothing else may.
  for (const p of problems) if (!expectedRefusal(p)) fail(p);
  if (problems.filter(expectedRefusal).length > 2) fail("more refusals than the one provoked: " + problems.join("; "));
  console.log(`run ${run.id}: ${run.outcome} (${run.reason}); frames ${ds.framesRendered}, points ${ds.points}; report "${title}" with ${figures} figures; ${analysis.text.trim()} (${analysisFigures} figures); gap ticks ${JSON.stringify(tickSets)}; ${shots.join("; ")}`);
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(h.deadline);
  h.finish();
});
