// What the console's Chromium tests share: a temp folder, failures collected and the run ended
// cleanly (browser closed, server stopped, its log shown on failure), the real `hilbench serve`
// started on a free port (again on the same port after a kill), waitFor with the page's state in
// the failure, Debian's Chromium through puppeteer-core, and PNGs decoded to check screenshots.
import { spawn } from "node:child_process";
import { existsSync, mkdtempSync, openSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { inflateSync } from "node:zlib";
import puppeteer from "puppeteer-core";

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
export const dataset = (page) => page.evaluate(() => ({ ...document.body.dataset }));

// A test's harness: h.dir (its temp folder), h.fail(message), h.finish() (exits), a deadline.
export function harness(prefix, deadlineS) {
  const h = { dir: mkdtempSync(join(tmpdir(), prefix)), failed: false, server: null, browser: null, listen: "127.0.0.1:0" };
  h.fail = (message) => {
    h.failed = true;
    console.error("FAIL: " + message);
  };
  h.finish = async () => {
    if (h.browser) await h.browser.close().catch(() => {});
    if (h.server && h.server.exitCode === null) h.server.kill("SIGTERM");
    if (h.failed && existsSync(join(h.dir, "server.log"))) console.error("---- server log ----\n" + readFileSync(join(h.dir, "server.log"), "utf8"));
    if (h.failed || process.env.HIL_KEEP_SCREENSHOTS) console.error("the server log, runs and screenshots are in " + h.dir);
    else rmSync(h.dir, { recursive: true, force: true });
    process.exit(h.failed ? 1 : 0);
  };
  h.deadline = setTimeout(() => {
    h.fail(`timed out after ${deadlineS} s`);
    h.finish();
  }, deadlineS * 1000);
  // `hilbench serve` on the configs folder given, runs under h.dir/runs; the base URL. A second
  // call (after a kill) listens on the same port, so an open page reconnects to it.
  h.startServer = async (exe, configs) => {
    rmSync(join(h.dir, "port"), { force: true });
    const log = openSync(join(h.dir, "server.log"), "a");
    h.server = spawn(exe, ["serve", "--listen", h.listen, "--configs", configs, "--runs-dir", join(h.dir, "runs"),
      "--port-file", join(h.dir, "port")], { stdio: ["ignore", log, log] });
    for (let i = 0; i < 600 && !existsSync(join(h.dir, "port")); ++i) await sleep(100);
    if (!existsSync(join(h.dir, "port"))) throw new Error("hilbench serve did not start");
    const port = Number(readFileSync(join(h.dir, "port"), "utf8"));
    h.listen = "127.0.0.1:" + port;
    return `http://127.0.0.1:${port}`;
  };
  h.launch = async () => {
    h.browser = await puppeteer.launch({ executablePath: process.env.HIL_CHROMIUM || "/usr/bin/chromium", headless: true,
      args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"] });
    return h.browser;
  };
  // Waits until fn(arg) is true in the page; false (and a failure naming what, with the page's
  // data-* state) when it is not within timeoutMs.
  h.waitFor = async (page, what, fn, arg, timeoutMs = 20_000) => {
    try {
      await page.waitForFunction(fn, { timeout: timeoutMs, polling: 50 }, arg);
      return true;
    } catch (e) {
      h.fail(what + " (within " + timeoutMs / 1000 + " s): " + JSON.stringify(await dataset(page).catch(() => ({}))) + " message: " +
        JSON.stringify(await page.$eval("#message", (m) => m.textContent).catch(() => "")));
      return false;
    }
  };
  // A page on the console at 1400x900 (its console and page errors pushed to `problems`), once
  // the campaign `campaign` is listed; null (and a failure) when it is not.
  h.openConsole = async (base, campaign, problems) => {
    const page = await h.browser.newPage();
    page.on("console", (m) => { if (m.type() === "error") problems.push(`console error: ${m.text()}`); });
    page.on("pageerror", (e) => problems.push(`page error: ${e.message}`));
    await page.setViewport({ width: 1400, height: 900 });
    await page.goto(base + "/", { waitUntil: "load" });
    const listed = await h.waitFor(page, "campaigns listed",
      (c) => [...document.querySelectorAll("#campaign option")].some((o) => o.value === c), campaign);
    return listed ? page : null;
  };
  return h;
}

// The pixels of an 8-bit RGB or RGBA PNG (what Chromium writes), decoded here so that the check
// does not trust the browser that drew them.
export function decodePng(buf) {
  if (buf.readUInt32BE(0) !== 0x89504e47) throw new Error("not a PNG");
  let off = 8;
  let width = 0, height = 0, channels = 0;
  const idat = [];
  while (off < buf.length) {
    const len = buf.readUInt32BE(off);
    const type = buf.toString("latin1", off + 4, off + 8);
    const data = buf.subarray(off + 8, off + 8 + len);
    if (type === "IHDR") {
      width = data.readUInt32BE(0);
      height = data.readUInt32BE(4);
      if (data[8] !== 8 || data[12] !== 0 || (data[9] !== 2 && data[9] !== 6)) throw new Error("PNG not 8-bit RGB(A), non-interlaced");
      channels = data[9] === 6 ? 4 : 3;
    } else if (type === "IDAT") {
      idat.push(data);
    }
    off += 12 + len;
  }
  const raw = inflateSync(Buffer.concat(idat));
  const stride = width * channels;
  const out = Buffer.alloc(height * stride);
  for (let y = 0; y < height; ++y) {
    const filter = raw[y * (stride + 1)];
    const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; ++x) {
      const a = x >= channels ? out[y * stride + x - channels] : 0;
      const b = y > 0 ? out[(y - 1) * stride + x] : 0;
      const c = x >= channels && y > 0 ? out[(y - 1) * stride + x - channels] : 0;
      let v = line[x];
      if (filter === 1) v += a;
      else if (filter === 2) v += b;
      else if (filter === 3) v += (a + b) >> 1;
      else if (filter === 4) {
        const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      } else if (filter !== 0) throw new Error("PNG filter " + filter);
      out[y * stride + x] = v & 255;
    }
  }
  return { width, height, channels, pixels: out };
}

// Distinct colours and the share of pixels unlike the most common one (the background).
export function inkOf(png) {
  const counts = new Map();
  const n = png.width * png.height;
  for (let i = 0; i < n; ++i) {
    const o = i * png.channels;
    const key = (png.pixels[o] << 16) | (png.pixels[o + 1] << 8) | png.pixels[o + 2];
    counts.set(key, (counts.get(key) || 0) + 1);
  }
  const most = Math.max(...counts.values());
  return { colours: counts.size, inkShare: 1 - most / n };
}

