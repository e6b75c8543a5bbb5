// The operator console's words (inlined first of its scripts): what every panel says the same way.
// A run's or campaign's name is quoted where it stands in a sentence (a run named `none` read as
// "nothing"), counts take their plural, times are the wall clock's, the loop's scheduling is said
// in words, and a run's end names its outcome, when and why.
"use strict";
window.hilWords = (() => {
  const quoted = (name) => "'" + String(name ?? "?") + "'";
  const run = (name) => "run " + quoted(name);
  const plural = (n, one, many) => n + " " + (n === 1 ? one : many || one + "s");
  // HH:MM:SS (UTC, as the server's records) of an ISO time or of milliseconds since the epoch.
  function clock(t) {
    const ms = typeof t === "number" ? t : Date.parse(t || "");
    return Number.isFinite(ms) ? new Date(ms).toISOString().slice(11, 19) : "?";
  }
  // RtSetup::describe() ("SCHED_FIFO 80, CPU 1" / "SCHED_OTHER, any CPU") in words.
  function realtime(sched) {
    const m = /^SCHED_(FIFO|OTHER)(?: (\d+))?, (?:CPU (\d+)|any CPU)$/.exec(String(sched || ""));
    if (!m) return String(sched || "–");
    const policy = m[1] === "FIFO" ? "real-time scheduling at priority " + m[2] + " (SCHED_FIFO)" : "normal scheduling, not real-time (SCHED_OTHER)";
    return policy + ", " + (m[3] !== undefined ? "pinned to CPU " + m[3] : "on any CPU");
  }
  const kRealtimeTip = "How the loop's thread is scheduled: real-time priority (SCHED_FIFO, 1-99, higher runs first) or the normal " +
    "scheduler, and the CPU it is pinned to (the rig file's loop: priority and cpu).";
  // The rig file's loop.cpu_dma_latency_us as the loop_start event records it: the µs asked of
  // /dev/cpu_dma_latency, or the refusal's text.
  function cpuLatency(v) {
    if (typeof v === "number") return "CPU idle states limited to " + v + " µs wake-up latency (/dev/cpu_dma_latency)";
    return v ? "CPU idle states not limited: " + v : "CPU idle states left alone";
  }
  // How a run ended (a status's last_run, a run_end notice): "run 'a' of c aborted at 01:02:03: why".
  function ended(r, opts = {}) {
    if (!r) return "";
    const when = r.stop_utc ? " at " + clock(r.stop_utc) : "";
    return run(r.run) + (opts.noCampaign ? "" : " of " + (r.campaign || "?")) + " " + (r.outcome || "?") + when + (r.reason ? ": " + r.reason : "");
  }
  return { quoted, run, plural, clock, realtime, kRealtimeTip, cpuLatency, ended };
})();
