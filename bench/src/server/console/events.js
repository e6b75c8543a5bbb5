// The operator console's events (inlined before console.js). A run's events.jsonl is followed by
// byte offset (GET /api/runs/{id}/events?offset=N, server/event_feed.hpp): each look fetches only
// what was appended, so what a second of run costs does not grow with the run (the whole file
// every second froze the page on a soak). Loop statistics (overruns, limited commands) arrive
// summarised per second with the worst and are shown one line per run and kind, whose count,
// seconds and worst update as they come (a line a second filled the panel); operator actions,
// injections, interlocks and faults are all kept (never capped, never twice: the page no longer
// adds its own copy of what the file records) with their fields in words, filterable by group.
// For tests: body data-event-bytes (bytes of event answers fetched), data-event-fetches.
"use strict";
window.hilEvents = function hilEvents({ $, body, apiText, ApiRefusal, onMarks }) {
  const W = window.hilWords;
  // Each kind's group, for the filter. What the operator or the interlocks did is marked on the plots.
  const groups = {
    gap_change: "operator", gap_programme: "operator", faults_cleared: "operator", stop_request: "operator",
    abort_request: "operator", stopped: "operator", refused: "operator",
    sensor_fault: "fault", drive_fault: "fault", rig_fault: "fault", fault_expired: "fault", rig_error: "fault",
    trip: "safety", safe_state: "safety", drive_not_disabled: "safety", warning: "safety", link: "safety",
    overrun: "loop", cmd_limited: "loop", dropped: "loop",
    run_start: "run", run_end: "run", loop_start: "run", campaign_end: "run", interrupted: "run",
  };
  const kMarked = new Set(["gap_change", "gap_programme", "sensor_fault", "drive_fault", "rig_fault", "fault_expired",
    "faults_cleared", "stop_request", "abort_request", "trip", "safe_state", "stopped"]);
  const groupOf = (kind) => groups[kind] || "other";
  const local = [];          // what this page saw or did that no file records
  const feeds = new Map();   // run folder -> { offset, events, summaries (Map "kind|t0" -> summary), busy }
  let currentDir = "";
  let bytes = 0, fetches = 0;
  body.dataset.eventBytes = "0";
  body.dataset.eventFetches = "0";

  // An event's fields in words: units from the name's suffix, durations read out, empty ones left out.
  const kUnits = [["_deg", " deg"], ["_mpa", " MPa"], ["_kpa", " kPa"], ["_us", " µs"], ["_ms", " ms"], ["_s", " s"]];
  // What a few kinds say in a sentence of their own; the rest list their fields.
  const kSaid = {
    gap_change: (e) => "true gap " + (typeof e.gap_deg === "number" ? String(+e.gap_deg.toFixed(6)) : "?") + " deg from now on",
    gap_programme: () => "the gap follows the campaign's programme again",
    loop_start: (e) => [W.realtime(e.sched), W.cpuLatency(e.cpu_dma_latency), e.warning, e.mlock_warning].filter((x) => x).join("; "),
  };
  function describe(e) {
    if (kSaid[e.kind]) return kSaid[e.kind](e);
    // "mark" is the plots' label of the event, made of the fields listed here.
    const skip = new Set(["utc", "kind", "source", "t_s", "period", "reason", "mark"]);
    const parts = e.reason ? [String(e.reason)] : [];
    for (const [k, v] of Object.entries(e)) {
      if (skip.has(k) || v === null || v === "" || (Array.isArray(v) && v.length === 0)) continue;
      if (k === "duration_s") {
        parts.push(v > 0 ? "for " + v + " s" : "until cleared");
        continue;
      }
      let name = k, unit = "";
      for (const [suffix, u] of kUnits) {
        if (k.endsWith(suffix)) {
          name = k.slice(0, -suffix.length);
          unit = u;
          break;
        }
      }
      const value = typeof v === "number" ? String(+v.toFixed(6)) : typeof v === "boolean" ? (v ? "yes" : "no") :
        typeof v === "object" ? JSON.stringify(v) : String(v);
      parts.push(name.replaceAll("_", " ") + " " + value + unit);
    }
    return parts.join(", ");
  }
  // A run's per-second summaries of one kind as one line: the count, the seconds, the worst.
  function groupText(kind, list) {
    let count = 0, worst = null;
    for (const s of list) {
      count += s.count;
      if (typeof s.worst_late_us === "number" && !(worst && worst.worst_late_us >= s.worst_late_us)) worst = s;
    }
    const t0 = list.reduce((m, s) => Math.min(m, s.t0_s), Infinity), t1 = list.reduce((m, s) => Math.max(m, s.t0_s), -Infinity) + 1;
    const what = kind === "overrun" ? (count === 1 ? "period overran" : "periods overran") : count === 1 ? "command limited" : "commands limited";
    return count + " " + what + " in " + W.plural(list.length, "second") + " of t " + t0 + "–" + t1 + " s" +
      (worst ? "; the worst " + worst.worst_late_us.toFixed(1) + " µs late at t " + worst.worst_t_s.toFixed(3) + " s" : "");
  }

  function add(kind, text, cls) {
    local.push({ utc: new Date().toISOString(), kind, text, cls, group: groupOf(kind) });
    render();
  }

  function render() {
    const filter = $("event-filter").value;
    const all = [...local];
    for (const [dir, feed] of feeds) {
      const where = dir === currentDir ? "" : " [" + dir + "]";
      for (const e of feed.events) {
        all.push({ utc: String(e.utc || ""), kind: String(e.kind || "?"), t_s: e.t_s, text: describe(e) + where,
          cls: e.kind === "trip" || e.kind === "safe_state" ? "trip" : "", group: groupOf(e.kind) });
      }
      const byKind = new Map();
      for (const s of feed.summaries.values()) {
        if (!byKind.has(s.kind)) byKind.set(s.kind, []);
        byKind.get(s.kind).push(s);
      }
      for (const [kind, list] of byKind) {
        const newest = list.reduce((a, b) => (String(b.utc || "") > String(a.utc || "") ? b : a));
        all.push({ utc: String(newest.utc || ""), kind: kind === "overrun" ? "overruns" : "limited", text: groupText(kind, list) + where,
          cls: "summary", group: "loop", count: list.reduce((n, s) => n + s.count, 0) });
      }
    }
    all.sort((a, b) => (a.utc < b.utc ? 1 : a.utc > b.utc ? -1 : 0));
    const shown = filter === "all" ? all : all.filter((e) => e.group === filter);
    $("event-list").replaceChildren(...shown.map((e) => {
      const li = document.createElement("li");
      li.className = e.cls || "";
      li.dataset.kind = e.kind;
      li.dataset.group = e.group;
      if (e.count !== undefined) li.dataset.count = String(e.count);
      const t = document.createElement("span");
      t.className = "t";
      t.textContent = e.utc.slice(11, 19) + (typeof e.t_s === "number" ? "  t " + e.t_s.toFixed(3) + " s" : "");
      const k = document.createElement("span");
      k.className = "kind";
      k.textContent = e.kind.replaceAll("_", " ") + ":";
      li.append(t, k, document.createTextNode(e.text));
      return li;
    }));
  }
  $("event-filter").addEventListener("change", render);

  // What was appended to a run's events.jsonl since the last look, until its end.
  async function follow(dir) {
    if (!dir) return;
    let feed = feeds.get(dir);
    if (!feed) feeds.set(dir, (feed = { offset: 0, events: [], summaries: new Map(), busy: false }));
    if (feed.busy) return;
    feed.busy = true;
    try {
      for (let more = true; more;) {
        const text = await apiText("/api/runs/" + encodeURIComponent(dir) + "/events?offset=" + feed.offset);
        bytes += text.length;
        body.dataset.eventBytes = String(bytes);
        body.dataset.eventFetches = String(++fetches);
        const r = JSON.parse(text);
        feed.events.push(...r.events);
        for (const s of r.summaries) {
          const key = s.kind + "|" + s.t0_s;
          const had = feed.summaries.get(key);
          if (!had) {
            feed.summaries.set(key, s);
          } else {  // a second split between two answers
            had.count += s.count;
            if (typeof s.worst_late_us === "number" && !(had.worst_late_us >= s.worst_late_us)) {
              had.worst_late_us = s.worst_late_us;
              had.worst_t_s = s.worst_t_s;
            }
          }
        }
        more = r.next_offset > feed.offset && r.next_offset < r.size;
        feed.offset = r.next_offset;
      }
      if (dir === currentDir) onMarks(feed.events.filter((e) => typeof e.t_s === "number" && kMarked.has(e.kind)));
      render();
    } catch (e) {
      if (!(e instanceof ApiRefusal) && !(e instanceof TypeError) && !(e instanceof SyntaxError)) throw e;  // the next look tries again
    } finally {
      feed.busy = false;
    }
  }

  function setCurrent(dir) {
    if (dir && dir !== currentDir) {
      currentDir = dir;
      onMarks([]);
    }
  }

  return { add, follow, setCurrent, current: () => currentDir, describe };
};
