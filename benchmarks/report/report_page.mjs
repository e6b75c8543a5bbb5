// The headless Chromium the report benchmarks open a page in (open_hour.mjs, zoom_hour.mjs,
// trace_report.mjs): a fresh browser per page, 1400x1000 px, a probe that notes the first frame
// after every plot was drawn, and the renderer's CPU time, which a loaded machine stretches far
// less than the wall clock. Needs the console test's packages (puppeteer-core).
import puppeteer from "puppeteer-core";

const chromium = process.env.HIL_CHROMIUM || "/usr/bin/chromium";

// Runs in the page before its scripts: window.__firstFrame resolves (ms since navigation start)
// at the first frame after the load event; report.js draws every plot in DOMContentLoaded, which
// ends before load, so that frame shows them all.
const probe = () => {
  window.__firstFrame = new Promise((done) =>
    addEventListener("load", () => requestAnimationFrame(() => setTimeout(() => done(performance.now())))));
};

// Opens `url` in a fresh browser and calls measure({ page, cdp, cpu, errors }) once it has loaded;
// cpu() is the renderer process's CPU ms so far (main and raster threads: Chrome's
// Performance.getMetrics ProcessTime). `beforeLoad(page, cdp)` runs before the navigation (tracing).
export async function inFreshPage(url, measure, { beforeLoad = null, args = [] } = {}) {
  const browser = await puppeteer.launch({ executablePath: chromium, headless: true,
    args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run", ...args] });
  try {
    const page = await browser.newPage();
    await page.setViewport({ width: 1400, height: 1000 });
    const errors = [];
    page.on("pageerror", (e) => errors.push(String(e)));
    await page.evaluateOnNewDocument(probe);
    const cdp = await page.target().createCDPSession();
    await cdp.send("Performance.enable");
    const cpu = async () => (await cdp.send("Performance.getMetrics")).metrics.find((m) => m.name === "ProcessTime").value * 1e3;
    if (beforeLoad) await beforeLoad(page, cdp);
    const cpu0 = await cpu();
    await page.goto(url, { waitUntil: "load" });
    return await measure({ page, cdp, cpu: async () => (await cpu()) - cpu0, errors });
  } finally {
    await browser.close();
  }
}

// What a benchmark table prints of a set of rounds: the median and the range.
export const median = (v) => v.slice().sort((a, b) => a - b)[Math.floor(v.length / 2)];
export const spread = (rounds, key) => {
  const v = rounds.map((r) => r[key]);
  return `${median(v).toFixed(0)} (${Math.min(...v).toFixed(0)}-${Math.max(...v).toFixed(0)})`;
};
