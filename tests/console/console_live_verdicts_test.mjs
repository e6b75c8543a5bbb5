// The console's verdicts while a run goes on (issue 41), in Debian's Chromium against the real
// `hilbench serve`: paper_adaptive's adaptive run with checks of its own, started by clicking:
//  - early_error_fails: |p_meas - p_ref| <= 1 Pa over [3, 3.5) s after the start, which the 2 kPa
//    transducer noise cannot meet: "pending" (with its limit) before 3 s, FAIL from the row of
//    3 s on, while the run is still RUNNING and the check's window still open (its message: the
//    worst at 3 s or later, fewer than the window's 500 periods checked);
//  - calm_first_second: no safe state over [0, 1) s: decided "pass" once its window closed;
//  - iae_at_end: a metric of the whole run, "pending until the end" while it runs;
//  - no_safe_state: its window is the whole run, so pending while it runs;
// then Stop: the run_end's final verdicts replace the live ones and agree with them (the failed
// one still FAIL, the decided pass still pass). The panel's every change is logged in the page by
// a MutationObserver, so the order (pending, then FAIL while running) is read, not sampled.
//   node console_live_verdicts_test.mjs HILBENCH_EXE SOURCE_DIR
import { mkdirSync, readFileSync, symlinkSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { harness } from "./harness.mjs";

const [exe, sourceDir] = process.argv.slice(2);
const h = harness("hil-console-live-", 120);
const fail = h.fail;
const failAtS = 3;

// paper_adaptive as "live_checks", 40 s long (the test stops it), its checks replaced by these.
function configs() {
  const c = join(h.dir, "configs");
  mkdirSync(join(c, "campaigns"), { recursive: true });
  for (const sub of ["plant", "rigs"]) symlinkSync(join(sourceDir, "configs", sub), join(c, sub));
  const paper = readFileSync(join(sourceDir, "configs", "campaigns", "paper_adaptive.yaml"), "utf8");
  const at = paper.indexOf("\nchecks:");
  if (at < 0 || !/^name: paper_adaptive\b/m.test(paper) || !/^duration_s: 18\b/m.test(paper)) throw new Error("paper_adaptive.yaml changed: name, duration_s or checks not found");
  const mine = paper.slice(0, at + 1).replace(/^name: paper_adaptive\b/m, "name: live_checks").replace(/^duration_s: 18\b/m, "duration_s: 40") +
    "checks:\n" +
    `  - {name: early_error_fails, runs: [adaptive], signal: pressure_error_mpa, delay_s: ${failAtS}, for_s: 0.5, max: 0.000001}\n` +
    "  - {name: calm_first_second, signal: safe_state, for_s: 1, max: 0}\n" +
    "  - {name: iae_at_end, metric: iae_mpa_s, max: 100}\n" +
    "  - {name: no_safe_state, signal: safe_state, max: 0}\n";
  writeFileSync(join(c, "campaigns", "live_checks.yaml"), mine);
  return c;
}

const t0 = Date.now();
async function main() {
  const base = await h.startServer(exe, configs());
  await h.launch();
  const problems = [];
  const page = await h.openConsole(base, "live_checks", problems);
  if (!page) return;
  // Every change of the panel, with the page's state at that moment.
  await page.evaluate(() => {
    window.verdictLog = [];
    const list = document.getElementById("verdict-list");
    new MutationObserver(() => {
      const rows = Object.fromEntries([...list.querySelectorAll("tr[data-check]")].map((tr) => [tr.dataset.check,
        { verdict: tr.dataset.verdict, live: tr.dataset.live, cells: [...tr.children].map((td) => td.textContent), title: tr.title }]));
      window.verdictLog.push({ state: document.body.dataset.state, rows });
    }).observe(list, { childList: true, subtree: true, characterData: true });
  });
  await page.select("#campaign", "live_checks");
  for (const r of await page.$$eval("#runs-choice input", (b) => b.map((x) => x.value))) if (r !== "adaptive") await page.click(`#runs-choice input[value="${r}"]`);
  await page.click("#start");
  const started = Date.now();

  if (!(await h.waitFor(page, "early_error_fails shown FAIL while the run goes on", () => {
    const tr = document.querySelector('#verdict-list tr[data-check="early_error_fails"]');
    return tr && tr.dataset.verdict === "fail" && tr.dataset.live === "1";
  }, undefined, 40_000))) return;
  const failSeen = (Date.now() - started) / 1000;
  const log = await page.evaluate(() => window.verdictLog);
  const firstFail = log.findIndex((e) => e.rows.early_error_fails?.verdict === "fail");
  const before = log.slice(0, firstFail);
  const pendingBefore = before.find((e) => e.state === "running" && e.rows.early_error_fails?.verdict === "pending" && e.rows.early_error_fails.live === "1");
  if (!pendingBefore) fail("early_error_fails never shown pending before its FAIL: " + JSON.stringify(before.slice(-3)));
  else {
    const p = pendingBefore.rows.early_error_fails;
    if (p.cells[1] !== "pending" || p.cells[3] !== "≤ 0.000001") fail("the pending row as shown: " + JSON.stringify(p));
    const iae = pendingBefore.rows.iae_at_end;
    if (!iae || iae.verdict !== "pending" || iae.cells[1] !== "pending until the end" || iae.cells[3] !== "≤ 100")
      fail("the metric while the run goes on: " + JSON.stringify(iae));
  }
  const atFail = log[firstFail];
  if (atFail.state !== "running") fail(`early_error_fails turned FAIL with the page in state ${atFail.state}, not running`);
  const f = atFail.rows.early_error_fails;
  if (f.cells[1] !== "FAIL" || !/^\d/.test(f.cells[2]) || f.cells[3] !== "≤ 0.000001") fail("the FAIL row as shown: " + JSON.stringify(f));
  // Decided inside its window (worst at 3 s or later, fewer periods checked than the window's 500),
  // not at its end.
  const worst = /worst at t = (\d+\.\d+) s, (\d+) periods checked/.exec(f.title);
  if (!worst || Number(worst[1]) < failAtS || Number(worst[1]) >= failAtS + 0.5 || Number(worst[2]) >= 500)
    fail("the FAIL was not decided inside its window: " + f.title);
  for (const name of ["iae_at_end", "no_safe_state"]) {
    if (atFail.rows[name]?.verdict !== "pending") fail(`${name} when early_error_fails turned FAIL: ${JSON.stringify(atFail.rows[name])}`);
  }
  // Its window closed at 1 s and nothing reopens it: decided before (or when) the failure shows.
  if (atFail.rows.calm_first_second?.verdict !== "pass" || atFail.rows.calm_first_second.cells[1] !== "pass")
    fail("calm_first_second when early_error_fails turned FAIL: " + JSON.stringify(atFail.rows.calm_first_second));
  const summary = await page.$eval("#verdict-summary", (e) => e.textContent);
  if (!/run 'adaptive' under way at \d+\.\d s: 1 failed, 1 pass so far, 2 pending/.test(summary)) fail("summary while running: " + summary);

  // Stop: the final verdicts replace the live ones and agree with them.
  await page.click("#stop");
  if (!(await h.waitFor(page, "the run's final verdicts", () => Number(document.body.dataset.verdictsFailed) >= 1 && document.body.dataset.liveRun === "", undefined, 30_000))) return;
  const final = Object.fromEntries(await page.$$eval("#verdict-list tr[data-check]", (rows) => rows.map((tr) => [tr.dataset.check, { verdict: tr.dataset.verdict, live: tr.dataset.live }])));
  const want = { early_error_fails: "fail", calm_first_second: "pass", iae_at_end: "pass", no_safe_state: "pass" };
  for (const [name, verdict] of Object.entries(want)) {
    if (final[name]?.verdict !== verdict || final[name].live !== "0") fail(`final ${name}: ${JSON.stringify(final[name])}, want ${verdict}`);
  }
  for (const p of problems) fail(p);
  console.log(`FAIL shown ${failSeen.toFixed(1)} s after Start (window at ${failAtS} s of run time); ${log.length} panel changes; ` +
    `summary while running "${summary}"; final ${JSON.stringify(final)}; ${((Date.now() - t0) / 1000).toFixed(1)} s in all (printed, not asserted)`);
}

main().catch((e) => fail(String(e?.stack ?? e))).finally(() => {
  clearTimeout(h.deadline);
  h.finish();
});
