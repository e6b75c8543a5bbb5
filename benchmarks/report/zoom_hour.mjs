// Does a one-hour 1 kHz run's served report open in under 2 s, and does a 10 s zoom draw every
// sample (issue 40, point 7)? The run is soak_random's `adaptive` run, one hour at 1 kHz (3.6 M
// rows; how its folder is made: below), served by the real
// `hilbench serve`, its report made once on the job worker (timed: "make"). Per round, a fresh
// headless Chromium (1400x1000, report_page.mjs) opens GET /api/runs/ID/report.html and reports:
//   first render  ms from navigation start to the first frame after every plot was drawn (all are
//                 drawn in DOMContentLoaded, which ends before load)
//   CPU to open   CPU ms of the page's renderer process to that frame (less stretched by the load)
//   zoom          ms from a 10 s x-zoom of the first time plot (its linked plots follow) until every
//                 time plot draws the window's samples fetched from the server, to the next frame
//   plot script   ms the DOMContentLoaded handlers took (parse each figure's JSON, build, draw)
//   drawn / file  rows each time plot holds in the window against telemetry.csv's rows there
//                 (counted here from the file): equal means every sample is drawn
// Given BASE_HILBENCH_EXE (another build, e.g. main's before this change), its `hilbench report`
// of the same run folder is opened from disk in alternating rounds (open only: it has no detail).
// Needs the console test's packages (puppeteer-core): run it from that test's node folder.
//   cp benchmarks/report/*.mjs build/tests/console/node/
//   node build/tests/console/node/zoom_hour.mjs build/bench/hilbench . 5 /tmp/hour_runs
// (RUNS_DIR's run is made when it holds none yet, ~1 min, 325 MB; kept for the next call.)
import { spawn, spawnSync } from "node:child_process";
import { createReadStream, existsSync, mkdirSync, mkdtempSync, readdirSync, readFileSync, renameSync, rmSync, statSync, symlinkSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { resolve, join } from "node:path";
import { createInterface } from "node:readline";
import { inFreshPage, spread } from "./report_page.mjs";

const [exe, sourceDir, roundsArg, runsArg, baseExe] = process.argv.slice(2);
if (!exe || !sourceDir) {
  console.error("usage: node zoom_hour.mjs HILBENCH_EXE SOURCE_DIR [ROUNDS] [RUNS_DIR] [BASE_HILBENCH_EXE]");
  process.exit(2);
}
const rounds = Number(roundsArg ?? 5);
const runs = resolve(runsArg ?? "/tmp/hil-hour-runs");
const configs = resolve(sourceDir, "configs");
const window10 = [1795, 1805];  // s: 10 s in the middle of the hour
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// The hour's run folder. `hilbench run` cannot record 3.6 M rows 100x faster than real time on a
// loaded 2-core machine (its recorder, CSV and MCAP, fell behind and the run aborted on a full
// ring at 25x), so the folder is put together from two real parts: run.json (and events.jsonl) of
// `hilbench run` of soak_random's adaptive run cut to 61 s (its gap drift starts at 60 s), its snapshot's duration set back to the
// hour; telemetry.csv of `hilbench sim` of the same run, the same RunLoop::cycle in lock-step.
mkdirSync(runs, { recursive: true });
let id = readdirSync(runs).find((d) => d.includes("soak_random") && d.includes("adaptive"));
if (!id) {
  const t0 = Date.now(), work = mkdtempSync(join(tmpdir(), "hil-zoom-hour-"));
  const run = (args) => {
    const r = spawnSync(resolve(exe), args, { stdio: ["ignore", "ignore", "inherit"] });
    if (r.status !== 0 && r.status !== 3) throw new Error(`hilbench ${args[0]}: exit ${r.status}`);  // 3: a check failed
  };
  run(["sim", join(configs, "campaigns", "soak_random.yaml"), "--runs", "adaptive", "--out", join(work, "sim"), "--quiet"]);
  mkdirSync(join(work, "configs", "campaigns"), { recursive: true });
  for (const sub of ["plant", "rigs"]) symlinkSync(join(configs, sub), join(work, "configs", sub));
  const yaml = readFileSync(join(configs, "campaigns", "soak_random.yaml"), "utf8");
  if (!/^duration_s: 3600\b/m.test(yaml)) throw new Error("soak_random.yaml: duration_s: 3600 not found");
  writeFileSync(join(work, "configs", "campaigns", "soak_random.yaml"), yaml.replace(/^duration_s: 3600\b/m, "duration_s: 61"));
  run(["run", join(work, "configs", "campaigns", "soak_random.yaml"), "--rig", "sim", "--runs", "adaptive", "--speed", "10",
    "--out", runs, "--configs", join(work, "configs"), "--no-mlock", "--quiet"]);
  id = readdirSync(runs).find((d) => d.includes("soak_random") && d.includes("adaptive"));
  const dir = join(runs, id), record = JSON.parse(readFileSync(join(dir, "run.json"), "utf8"));
  record.config.campaign_yaml = record.config.campaign_yaml.replace(/^duration_s: 61\b/m, "duration_s: 3600");
  record.duration_s = 3600;
  writeFileSync(join(dir, "run.json"), JSON.stringify(record, null, 1));
  rmSync(join(dir, "telemetry.mcap"), { force: true });
  renameSync(join(work, "sim", "soak_random", "adaptive", "telemetry.csv"), join(dir, "telemetry.csv"));
  rmSync(work, { recursive: true, force: true });
  console.log(`made ${id} in ${((Date.now() - t0) / 1000).toFixed(0)} s`);
}
const csv = join(runs, id, "telemetry.csv");
rmSync(join(runs, id, "report.html"), { force: true });  // made by this build's report writer

// telemetry.csv's rows in the window, and all of them, read here.
let fileRows = 0, inWindow = 0;
for await (const line of createInterface({ input: createReadStream(csv) })) {
  if (!line || line[0] === "#" || line[0] === "t") continue;
  fileRows++;
  const t = parseFloat(line);
  if (t >= window10[0] && t <= window10[1]) inWindow++;
}

const port = join(runs, "..", `hil-zoom-hour-port-${process.pid}`);
const server = spawn(resolve(exe), ["serve", "--listen", "127.0.0.1:0", "--configs", configs, "--runs-dir", runs, "--port-file", port,
  "--no-mlock"], { stdio: ["ignore", "ignore", "inherit"] });
try {
  for (let i = 0; i < 300 && !existsSync(port); ++i) await sleep(100);
  const base = "http://127.0.0.1:" + Number(readFileSync(port, "utf8"));
  const url = `${base}/api/runs/${id}/report.html`;
  const m0 = Date.now();
  const made = await fetch(url + "?wait=1");
  if (!made.ok) throw new Error("report: HTTP " + made.status + " " + (await made.text()));
  const makeMs = Date.now() - m0, pageBytes = statSync(join(runs, id, "report.html")).size;

  const measure = (url, zoomIt) =>
    inFreshPage(url, async ({ page, cpu, errors }) => {
      const opened = await page.evaluate(async () => {
        const first = await window.__firstFrame;
        const nav = performance.getEntriesByType("navigation")[0];
        const charts = window.hilReport.charts;
        return { first, script: nav.domContentLoadedEventEnd - nav.domContentLoadedEventStart, plots: Number(document.body.dataset.plots), errors: Number(document.body.dataset.plotErrors),
          rows: charts.reduce((n, c) => n + (c.rows ? c.rows.length : 0), 0),
          thinned: charts.filter((c) => c.fig.querySelector(".hil-res.hil-thin")).length };
      });
      const openCpu = await cpu();
      if (!zoomIt) return { ...opened, openCpu, zoom: NaN, drawn: [], notes: [], pageErrors: errors };
      const zoom = await page.evaluate(async (w) => {
        const group = window.hilReport.charts.filter((c) => c.group === "t");
        const t0 = performance.now();
        group[0].graph.updateOptions({ dateWindow: w });
        while (!group.every((c) => c.fig.querySelector(".hil-res.hil-full, .hil-res.hil-error")) && performance.now() - t0 < 30000)
          await new Promise((r) => setTimeout(r, 5));
        await new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
        const ms = performance.now() - t0;
        const drawn = group.map((c) => {
          let n = 0;
          for (let i = 0; i < c.graph.numRows(); ++i) {
            const x = c.graph.getValue(i, 0);
            if (x >= w[0] && x <= w[1]) n++;
          }
          return n;
        });
        return { ms, drawn, notes: group.map((c) => c.fig.querySelector(".hil-res").className) };
      }, window10);
      return { ...opened, openCpu, zoom: zoom.ms, drawn: zoom.drawn, notes: zoom.notes, pageErrors: errors };
    });

  let baseUrl = null;
  if (baseExe) {
    const r = spawnSync(resolve(baseExe), ["report", join(runs, id), "--out", join(runs, "..", "base_report.html"), "--quiet"], { stdio: "inherit" });
    if (r.status !== 0) throw new Error("base hilbench report: exit " + r.status);
    baseUrl = "file://" + resolve(runs, "..", "base_report.html");
  }
  const rs = [], bs = [];
  for (let i = 0; i < rounds; ++i) {
    rs.push(await measure(url, true));
    if (baseUrl) bs.push(await measure(baseUrl, false));
  }
  const f = spread;
  const drawn = [...new Set(rs.flatMap((r) => r.drawn))];
  const bad = rs.filter((r) => r.errors || r.pageErrors.length || r.notes.some((n) => !n.includes("hil-full")));
  console.log(`run ${id}: telemetry.csv ${fileRows} rows (${(statSync(csv).size / 1e6).toFixed(0)} MB), ${inWindow} in ${window10.join("-")} s; ` +
    `report made in ${makeMs} ms, ${(pageBytes / 1e6).toFixed(2)} MB; ${rounds} rounds, median (min-max)`);
  console.log("| report | plots (thinned) | table rows | first render (ms) | plot script (ms) | CPU to open (ms) | 10 s zoom, every sample (ms) | rows drawn in the 10 s / in the file |");
  console.log("|---|---|---|---|---|---|---|---|");
  console.log(`| this tree, served | ${rs[0].plots} (${rs[0].thinned}) | ${rs[0].rows} | ${f(rs, "first")} | ${f(rs, "script")} | ${f(rs, "openCpu")} | ${f(rs, "zoom")} | ` +
    `${drawn.join(", ")} / ${inWindow}${bad.length ? ` PROBLEMS in ${bad.length} rounds: ${JSON.stringify(bad[0].notes)} ${bad[0].pageErrors}` : ""} |`);
  if (bs.length) {
    console.log(`| base, from disk (${(statSync(resolve(runs, "..", "base_report.html")).size / 1e6).toFixed(2)} MB) | ${bs[0].plots} (${bs[0].thinned}) | ${bs[0].rows} | ` +
      `${f(bs, "first")} | ${f(bs, "script")} | ${f(bs, "openCpu")} | - | - |`);
  }
  if (bad.length || drawn.some((n) => n !== inWindow)) process.exitCode = 1;
} finally {
  server.kill("SIGTERM");
  rmSync(port, { force: true });
}
