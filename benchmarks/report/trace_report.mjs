// Where the time to open a report goes: a Chrome trace (devtools.timeline) of one page load in a
// fresh headless Chromium, summed by what the renderer's main thread did (parse HTML, compile and
// run script, style, layout, paint) and the raster threads, from navigation to the first frame
// after every plot was drawn. Per round, then the median of each row.
// Needs the console test's packages (puppeteer-core): run it from that test's node folder.
//   cp benchmarks/report/*.mjs build/tests/console/node/
//   node build/tests/console/node/trace_report.mjs URL_OR_FILE [ROUNDS]
import { resolve } from "node:path";
import { inFreshPage, median } from "./report_page.mjs";

const [target, roundsArg] = process.argv.slice(2);
if (!target) {
  console.error("usage: node trace_report.mjs URL_OR_FILE [ROUNDS]");
  process.exit(2);
}
const url = /^https?:|^file:/.test(target) ? target : "file://" + resolve(target);
const rounds = Number(roundsArg ?? 3);

// Top-level work on a thread: complete events (ph X) not inside another counted one.
const KINDS = { ParseHTML: "parse HTML", EvaluateScript: "script: evaluate", "v8.compile": "script: compile",
  FunctionCall: "script: call", EventDispatch: "script: event", TimerFire: "script: timer", FireAnimationFrame: "script: animation frame",
  RunMicrotasks: "script: microtasks", ParseAuthorStyleSheet: "style: parse", UpdateLayoutTree: "style: recalc", Layout: "layout",
  PrePaint: "pre-paint", Paint: "paint", "Layerize": "layerize", UpdateLayer: "paint", CompositeLayers: "composite", Commit: "commit (software canvases drawn)", RasterTask: "raster",
  MajorGC: "GC", MinorGC: "GC", "V8.GC_SCAVENGER": "GC", "BlinkGC.AtomicPhase": "GC", HitTest: "hit test" };

function summarise(events, endMs) {
  const threads = new Map();
  for (const e of events) if (e.ph === "M" && e.name === "thread_name") threads.set(`${e.pid}:${e.tid}`, e.args.name);
  // The page's navigation start (blink.user_timing), which performance.now() counts from; its
  // renderer process is the one measured.
  const navs = events.filter((e) => e.name === "navigationStart" && e.args && e.args.data && e.args.data.isLoadingMainFrame &&
    /^(https?|file):/.test(e.args.data.documentLoaderURL || ""));
  if (!navs.length) throw new Error("no navigationStart of the page in the trace");
  const t0 = navs[navs.length - 1].ts, pid = navs[navs.length - 1].pid;
  const where = (e) => {
    const th = threads.get(`${e.pid}:${e.tid}`) || "?";
    return e.pid !== pid ? null : th === "CrRendererMain" ? "main" : /Raster|Compositor/i.test(th) ? th.replace(/\d+$/, "") : null;
  };
  const inWindow = (e) => e.ph === "X" && e.ts >= t0 && (e.ts - t0) / 1e3 <= endMs && where(e);
  // Sums the outermost events that `pick` names (an event inside another counted one is not counted again).
  const sums = {};
  const add = (pick) => {
    const open = new Map();  // thread -> end of the counted event it is in
    for (const e of events.filter((e) => inWindow(e) && pick(e)).sort((a, b) => a.ts - b.ts)) {
      const key = `${e.pid}:${e.tid}`;
      if ((open.get(key) || 0) > e.ts) continue;
      open.set(key, e.ts + e.dur);
      const name = `${where(e)}: ${pick(e)}`;
      sums[name] = (sums[name] || 0) + e.dur / 1e3;
    }
  };
  add((e) => KINDS[e.name]);
  // How busy each thread was in all (its tasks), so that what the rows above miss shows.
  add((e) => (e.name === "ThreadControllerImpl::RunTask" ? "all its tasks" : null));
  // The main thread's events by self time (their time less that of the events inside them): what
  // the kinds above miss, e.g. a canvas rasterised at the frame's commit.
  const self = {}, stack = [];
  for (const e of events.filter((e) => inWindow(e) && where(e) === "main").sort((a, b) => a.ts - b.ts || b.dur - a.dur)) {
    while (stack.length && stack[stack.length - 1].ts + stack[stack.length - 1].dur <= e.ts) stack.pop();
    if (stack.length) self[stack[stack.length - 1].name] -= e.dur / 1e3;
    self[e.name] = (self[e.name] || 0) + e.dur / 1e3;
    stack.push(e);
  }
  for (const [name, ms] of Object.entries(self).sort((a, b) => b[1] - a[1]).slice(0, 8)) sums[`main, self time: ${name}`] = ms;
  return sums;
}

const all = [];
for (let i = 0; i < rounds; ++i) {
  let trace = null;
  const r = await inFreshPage(url, async ({ page, cpu }) => {
    const first = await page.evaluate(() => window.__firstFrame);
    const openCpu = await cpu();
    trace = JSON.parse(Buffer.from(await page.tracing.stop()).toString("utf8"));
    const nav = await page.evaluate(() => {
      const n = performance.getEntriesByType("navigation")[0];
      return { responseEnd: n.responseEnd, domInteractive: n.domInteractive, dclStart: n.domContentLoadedEventStart,
        dclEnd: n.domContentLoadedEventEnd, load: n.loadEventStart, bytes: n.transferSize || n.encodedBodySize,
        dom: document.getElementsByTagName("*").length };
    });
    return { first, openCpu, ...nav };
  }, { beforeLoad: (page) => page.tracing.start({ categories: ["devtools.timeline", "v8", "toplevel", "blink.user_timing", "disabled-by-default-devtools.timeline"] }) });
  const sums = summarise(trace.traceEvents, r.first);
  all.push({ ...r, sums });
  console.log(`round ${i + 1}: first frame ${r.first.toFixed(0)} ms, CPU ${r.openCpu.toFixed(0)} ms; response end ${r.responseEnd.toFixed(0)}, ` +
    `DOM interactive ${r.domInteractive.toFixed(0)}, DOMContentLoaded ${r.dclStart.toFixed(0)}-${r.dclEnd.toFixed(0)}, load ${r.load.toFixed(0)} ms; ` +
    `${(r.bytes / 1e3).toFixed(0)} kB, ${r.dom} elements`);
}
const names = [...new Set(all.flatMap((r) => Object.keys(r.sums)))].sort();
console.log(`| work (top level, until the first frame) | median of ${rounds} (ms) |`);
console.log("|---|---|");
for (const n of names) console.log(`| ${n} | ${median(all.map((r) => r.sums[n] || 0)).toFixed(0)} |`);
