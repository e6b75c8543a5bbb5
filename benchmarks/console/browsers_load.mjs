// Does watching slow the loop? The real `hilbench serve` runs paper_adaptive's adaptive run (18 s
// at 1 kHz) with 0 and with N Chromium instances showing the console (each its own browser, all
// following the live plots), in turns; prints the loop's figures from each run's run.json.
// Needs the console test's packages (puppeteer-core): run it from that test's node folder.
//   cp benchmarks/console/browsers_load.mjs build/tests/console/node/ &&
//   node build/tests/console/node/browsers_load.mjs build/bench/hilbench . 5 2
import { spawn } from "node:child_process";
import { existsSync, mkdtempSync, openSync, readFileSync, readdirSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join, resolve } from "node:path";
import puppeteer from "puppeteer-core";

const [exe, sourceDir, browsersArg, roundsArg] = process.argv.slice(2);
const browsers = Number(browsersArg ?? 5), rounds = Number(roundsArg ?? 2);
const chromium = process.env.HIL_CHROMIUM || "/usr/bin/chromium";
const dir = mkdtempSync(join(tmpdir(), "hil-browsers-"));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

const server = spawn(resolve(exe), ["serve", "--listen", "127.0.0.1:0", "--configs", join(resolve(sourceDir), "configs"),
  "--runs-dir", join(dir, "runs"), "--port-file", join(dir, "port")], { stdio: ["ignore", openSync(join(dir, "log"), "a"), "inherit"] });
try {
  for (let i = 0; i < 600 && !existsSync(join(dir, "port")); ++i) await sleep(100);
  const base = `http://127.0.0.1:${Number(readFileSync(join(dir, "port"), "utf8"))}`;
  console.log("| browsers | wake-up p50 / p99 / p99.9 / max (µs) | compute p99 (µs) | overruns | rows written / lost | frames drawn per browser |");
  console.log("|---|---|---|---|---|---|");
  for (let round = 0; round < rounds; ++round) {
    for (const n of [0, browsers]) {
      const open = [];
      for (let i = 0; i < n; ++i) {
        const b = await puppeteer.launch({ executablePath: chromium, headless: true,
          args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"] });
        const page = await b.newPage();
        await page.setViewport({ width: 1400, height: 1000 });
        await page.goto(base + "/");
        open.push({ b, page });
      }
      const before = new Set(existsSync(join(dir, "runs")) ? readdirSync(join(dir, "runs")) : []);
      const r = await fetch(base + "/api/start", { method: "POST", headers: { "content-type": "application/json" },
        body: JSON.stringify({ campaign: "paper_adaptive", runs: ["adaptive"] }) });
      if (r.status !== 202) throw new Error("start: " + r.status + " " + (await r.text()));
      await sleep(1000);
      for (;;) {
        const s = await (await fetch(base + "/api/status")).json();
        if (s.state === "idle") break;
        await sleep(500);
      }
      const frames = [];
      for (const { b, page } of open) {
        frames.push(Number(await page.evaluate(() => document.body.dataset.framesRendered ?? -1)));
        await b.close();
      }
      const id = readdirSync(join(dir, "runs")).find((d) => !before.has(d));
      const run = JSON.parse(readFileSync(join(dir, "runs", id, "run.json"), "utf8"));
      const w = run.loop.wake_latency_us, c = run.loop.compute_us, t = run.telemetry;
      console.log(`| ${n} | ${w.p50_us} / ${w.p99_us} / ${w.p99_9_us} / ${w.max_us} | ${c.p99_us} | ${run.loop.overruns} | ` +
        `${t.rows_written} / ${t.rows_lost} | ${frames.length ? frames.join(", ") : "-"} |`);
    }
  }
} finally {
  server.kill("SIGTERM");
  await sleep(500);
  rmSync(dir, { recursive: true, force: true });
}
