// Two (or more) report pages opened from disk in alternating rounds, each in a fresh headless
// Chromium (report_page.mjs), so that every page sees the same machine: first render (ms from
// navigation to the first frame after every plot was drawn), plot script (the DOMContentLoaded
// handlers) and the renderer's CPU to that frame, median (min-max). For an A/B of one change to
// report.js: the same page with the old text swapped in, e.g. with sed.
// Needs the console test's packages (puppeteer-core): run it from that test's node folder.
//   cp benchmarks/report/*.mjs build/tests/console/node/
//   node build/tests/console/node/ab_pages.mjs ROUNDS A.html B.html
import { resolve } from "node:path";
import { inFreshPage, spread } from "./report_page.mjs";

const [roundsArg, ...files] = process.argv.slice(2);
if (!(Number(roundsArg) > 0) || files.length < 1) {
  console.error("usage: node ab_pages.mjs ROUNDS PAGE.html [PAGE.html...]");
  process.exit(2);
}
const results = Object.fromEntries(files.map((f) => [f, []]));
for (let i = 0; i < Number(roundsArg); ++i) {
  for (const f of files) {
    results[f].push(await inFreshPage("file://" + resolve(f), async ({ page, cpu, errors }) => {
      const opened = await page.evaluate(async () => {
        const first = await window.__firstFrame;
        const nav = performance.getEntriesByType("navigation")[0];
        return { first, script: nav.domContentLoadedEventEnd - nav.domContentLoadedEventStart, errors: Number(document.body.dataset.plotErrors) };
      });
      return { ...opened, cpu: await cpu(), pageErrors: errors.length };
    }));
  }
}
console.log(`${roundsArg} rounds, median (min-max)`);
console.log("| page | first render (ms) | plot script (ms) | CPU to open (ms) |");
console.log("|---|---|---|---|");
for (const [f, rs] of Object.entries(results)) {
  const bad = rs.filter((r) => r.errors || r.pageErrors).length;
  console.log(`| ${f}${bad ? ` ERRORS in ${bad} rounds` : ""} | ${spread(rs, "first")} | ${spread(rs, "script")} | ${spread(rs, "cpu")} |`);
}
