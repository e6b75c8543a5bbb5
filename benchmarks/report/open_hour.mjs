// How fast does a report of a one-hour 1 kHz campaign open and zoom in Chromium, with the plotting
// layer of this tree (dygraphs) against the one of an older commit (the hand-written canvas
// report.js)? The same page is measured twice: as written, and with its style and scripts swapped
// for the old commit's report.css and report.js. Given a BASE report (the same campaign written by
// another build, e.g. main's before a change to the decimation), the old layer draws BASE's data
// (what that layer drew when it was current) and BASE as written is measured too.
// Per layer and round, a fresh headless Chromium (report_page.mjs) opens the page from disk and reports:
//   first render  ms from navigation start to the first frame after every plot was drawn
//   plot script   ms the DOMContentLoaded handlers took (parsing the data, building, drawing)
//   zoom          ms from a 10x x-zoom of the first plot (its group follows) to the next frame
//   CPU to open   CPU ms of the page's renderer process (main and raster threads) from before
//                 navigation to the first frame (above); CPU to zoom: the same for the zoom
//   table rows    the rows of the tables dygraphs draws, summed over the plots (not for canvas)
// Needs the console test's packages (puppeteer-core): run it from that test's node folder.
//   build/bench/hilbench sim configs/campaigns/soak_random.yaml --no-telemetry --out /tmp/hour
//   cp benchmarks/report/*.mjs build/tests/console/node/ &&
//   node build/tests/console/node/open_hour.mjs /tmp/hour/soak_random/report.html . 42013a4 5 [BASE.html]
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync, statSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";
import { inFreshPage, spread } from "./report_page.mjs";

const [reportArg, sourceDir, oldRev, roundsArg, baseArg] = process.argv.slice(2);
if (!reportArg || !sourceDir || !oldRev) {
  console.error("usage: node open_hour.mjs REPORT.html SOURCE_DIR OLD_COMMIT [ROUNDS] [BASE_REPORT.html]");
  process.exit(2);
}
const rounds = Number(roundsArg ?? 5);
const dir = mkdtempSync(join(tmpdir(), "hil-open-hour-"));
const git = (path) => execFileSync("git", ["-C", sourceDir, "show", `${oldRev}:${path}`], { encoding: "utf8" });

// The old layer reads every series' own x: a series written with the x of another ("xOf") gets it.
const ownX = (html) =>
  html.replace(/(<script type="application\/json" class="hil-data">)(.*?)(<\/script>)/gs, (all, open, json, close) => {
    const spec = JSON.parse(json);
    for (const s of spec.series || []) if (s.x === undefined && s.xOf !== undefined) s.x = spec.series[s.xOf].x, delete s.xOf;
    return open + JSON.stringify(spec).replace(/</g, "\\u003c") + close;
  });
const source = readFileSync(baseArg || reportArg, "utf8");
const styleAt = source.indexOf("<style>\n") + "<style>\n".length, styleEnd = source.indexOf("</style>");
const mainEnd = source.lastIndexOf("</main>\n") + "</main>\n".length;
if (styleAt < 8 || styleEnd < 0 || mainEnd < 8) throw new Error((baseArg || reportArg) + " is not a hilbench report");
const old = source.slice(0, styleAt) + git("analysis/report/src/report.css") + ownX(source.slice(styleEnd, mainEnd)) +
  '<div class="hil-tip" hidden></div>\n<script>\n' + git("analysis/report/src/report.js") + "</script>\n</body></html>\n";
const oldName = `canvas report.js (${oldRev})${baseArg ? ", base data" : ""}`;
const pages = { [`dygraphs (this tree)`]: resolve(reportArg) };
if (baseArg) pages["dygraphs, base report"] = resolve(baseArg);
pages[oldName] = join(dir, "old.html");
writeFileSync(pages[oldName], old);

const measure = (file) =>
  inFreshPage("file://" + file, async ({ page, cpu, errors }) => {
    const opened = await page.evaluate(async () => {
      const first = await window.__firstFrame;
      const nav = performance.getEntriesByType("navigation")[0];
      const charts = window.hilReport.charts, c = charts[0];
      return { first, script: nav.domContentLoadedEventEnd - nav.domContentLoadedEventStart,
        rows: c.graph ? charts.reduce((n, o) => n + (o.rows ? o.rows.length : 0), 0) : null,
        plots: Number(document.body.dataset.plots), errors: Number(document.body.dataset.plotErrors),
        group: charts.filter((o) => o.group && o.group === c.group).length };
    });
    const cpu1 = await cpu();
    const zoom = await page.evaluate(async () => {
      const c = window.hilReport.charts[0];
      const frame = () => new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
      // 10x zoom around the middle of the first plot's full x range, the way each layer applies one.
      const [a, b] = c.graph ? c.graph.xAxisRange() : c.fullX, m = (a + b) / 2, h = (b - a) / 20;
      const t0 = performance.now();
      if (c.graph) c.graph.updateOptions({ dateWindow: [m - h, m + h] });
      else c.setView([m - h, m + h]);
      await frame();
      return performance.now() - t0;
    });
    const cpu2 = await cpu();
    return Object.assign(opened, { zoom, openCpu: cpu1, zoomCpu: cpu2 - cpu1, pageErrors: errors.length });
  }, { args: ["--allow-file-access-from-files"] });

const mb = (file) => (statSync(file).size / 1e6).toFixed(2) + " MB";
console.log(`report: ${Object.entries(pages).map(([k, f]) => `${k} ${mb(f)}`).join(", ")}; ${rounds} rounds, median (min-max)`);
console.log("| plotting layer | plots | table rows | first render (ms) | plot script (ms) | 10x zoom of a linked plot (ms) | CPU to open (ms) | CPU to zoom (ms) |");
console.log("|---|---|---|---|---|---|---|---|");
const results = Object.fromEntries(Object.keys(pages).map((k) => [k, []]));
for (let i = 0; i < rounds; ++i) for (const [name, file] of Object.entries(pages)) results[name].push(await measure(file));
for (const [name, rs] of Object.entries(results)) {
  const f = (key) => spread(rs, key);
  const bad = rs.filter((r) => r.errors || r.pageErrors).length;
  console.log(`| ${name} | ${rs[0].plots} (group of ${rs[0].group})${bad ? ` ERRORS in ${bad} rounds` : ""} | ${rs[0].rows ?? "-"} | ` +
    `${f("first")} | ${f("script")} | ${f("zoom")} | ${f("openCpu")} | ${f("zoomCpu")} |`);
}
rmSync(dir, { recursive: true, force: true });
