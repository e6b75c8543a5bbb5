// The operator console's verdict panel (inlined before console.js): the campaign's checks
// (`checks:` in its YAML, judged by the server with the one evaluator of `hilbench sim`,
// server/run_verdicts.hpp) per run, as pass / FAIL / skipped with the value against its limit. They
// arrive on the telemetry WebSocket in each run's run_end message, so a run's verdicts show the
// moment it ends, while the campaign's later runs go on; a page opened later takes the last
// campaign's from the status (last.runs[].checks). While a run goes on, the stream's status
// messages carry its checks as they stand (live: a signal check that failed is FAIL at once, one
// whose window closed within its limit "pass so far", one none of whose windows can open again
// decided, the rest pending; a metric of the whole run "pending until the end"); its run_end
// replaces them with the final ones. The panel holds one campaign's runs (by its start time, so
// the same campaign run again clears it), each with its run folder; a run that ended without its
// final verdicts (interrupted by a server that died, found by the restarted server's last_run) is
// said so, its checks as they last stood, the undecided ones "not judged".
// For tests: body data-verdicts-failed / data-verdicts-passed (counts of ended runs' verdicts),
// data-live-run / data-live-failed / data-live-pending (the run under way's), data-verdicts-dirs
// (the run folders shown, comma-separated), data-verdicts-unjudged (run folders that ended without
// final verdicts); each row data-run, data-dir, data-check, data-verdict (pending | passing | pass
// | fail | skipped | not-judged) and data-live ("1" while the run goes on).
"use strict";
window.hilVerdicts = function hilVerdicts({ $, body }) {
  const W = window.hilWords;
  // The campaign shown: its start time (or "run:" + folder for a run known only by its end) and name.
  let held = { key: "", campaign: "" };
  // run name -> { dir, state: "running" | outcome, stop_utc, checks: {passed, failed, skipped, results} | live {run, t_s, results} | null, final }
  const runs = new Map();
  body.dataset.verdictsFailed = "0";
  body.dataset.verdictsPassed = "0";
  body.dataset.liveRun = "";
  body.dataset.liveFailed = "0";
  body.dataset.livePending = "0";
  body.dataset.verdictsDirs = "";
  body.dataset.verdictsUnjudged = "";
  const shown = { fail: "FAIL", passing: "pass so far" };

  const num = (v) => (typeof v === "number" && isFinite(v) ? String(+v.toPrecision(4)) : "–");
  function limit(r) {
    const parts = [];
    if (typeof r.min === "number") parts.push("≥ " + num(r.min));
    if (typeof r.max === "number") parts.push("≤ " + num(r.max));
    return parts.join(" and ") || "–";
  }
  const checksOf = (m) => (m.checks && Array.isArray(m.checks.results) ? m.checks : null);

  // The panel is `key`'s campaign from now on: another's runs go.
  function own(key, campaign) {
    if (key === held.key) return;
    runs.clear();
    held = { key, campaign: campaign || "" };
  }
  // A campaign's identity: its start time; a page of an older server without it: its name.
  const keyOf = (m) => m.campaign_started_utc || m.started_utc || "name:" + (m.campaign || "");

  function row(run, v, r) {
    const tr = document.createElement("tr");
    const live = v.state === "running";
    const unjudged = !live && !v.final && !r.decided;  // its run ended before it was judged
    tr.dataset.run = run;
    tr.dataset.dir = v.dir || "";
    tr.dataset.check = r.check;
    tr.dataset.verdict = unjudged ? "not-judged" : r.verdict;
    tr.dataset.live = live ? "1" : "0";
    tr.title = r.message || "";  // what was measured against what, or why it was skipped
    const verdict = unjudged ? "not judged (" + v.state + ")" : shown[r.verdict] || (r.verdict === "pending" && r.at_end ? "pending until the end" : r.verdict);
    const cells = [run + " / " + r.check, verdict, num(r.value), limit(r)].map((t) => {
      const td = document.createElement("td");
      td.textContent = t;
      return td;
    });
    cells[1].className = "verdict verdict-" + (unjudged ? "pending" : r.verdict === "passing" ? "pass" : r.verdict);
    cells[2].className = cells[3].className = "num";
    tr.append(...cells);
    return tr;
  }
  function note(run, v) {
    const tr = document.createElement("tr");
    tr.dataset.run = run;
    tr.dataset.dir = v.dir || "";
    tr.dataset.verdict = v.state === "running" ? "pending" : "none";
    const td = document.createElement("td");
    td.colSpan = 4;
    td.textContent = v.state === "running" ? W.run(run) + " under way; its checks show as they are judged" :
      W.ended({ ...v, run, outcome: v.state }, { noCampaign: true }) + "; no checks judged";
    td.className = "about";
    tr.append(td);
    return tr;
  }
  const tally = (results) => {
    const t = { failed: 0, passing: 0, pending: 0 };
    for (const r of results) {
      if (r.verdict === "fail") ++t.failed;
      else if (r.verdict === "passing" || r.verdict === "pass") ++t.passing;
      else if (r.verdict === "pending") ++t.pending;
    }
    return t;
  };
  const asStood = (c) => (typeof c.t_s === "number" ? " at " + c.t_s.toFixed(1) + " s" : "");

  function render() {
    const rowsOut = [];
    let failed = 0, passed = 0, judged = false;
    const underWay = { run: "", failed: 0, pending: 0 };
    const texts = [];
    const unjudged = [];
    for (const [run, v] of runs) {
      if (!v.checks) {
        rowsOut.push(note(run, v));
        if (v.state !== "running" && v.state !== "completed") texts.push(W.ended({ ...v, run, outcome: v.state }, { noCampaign: true }));
        continue;
      }
      const results = v.checks.results || [];
      for (const r of results) rowsOut.push(row(run, v, r));
      if (v.state === "running") {
        const t = tally(results);
        underWay.run = run;
        underWay.failed = t.failed;
        underWay.pending = t.pending;
        texts.push(W.run(run) + " under way" + asStood(v.checks) + ": " + t.failed + " failed, " + t.passing + " pass so far, " + t.pending +
          " pending (metrics of the whole run are judged at its end)");
      } else if (!v.final) {
        const t = tally(results);
        unjudged.push(v.dir);
        failed += t.failed;
        texts.push(W.ended({ ...v, run, outcome: v.state }, { noCampaign: true }) + " — its checks were not judged to the end; as they stood" + asStood(v.checks) +
          ": " + t.failed + " failed, " + t.passing + " pass so far, " + t.pending + " not judged");
      } else {
        judged = true;
        for (const r of results) {
          if (r.verdict === "fail") ++failed;
          if (r.verdict === "pass") ++passed;
        }
      }
    }
    $("verdict-list").replaceChildren(...rowsOut);
    if (judged) texts.unshift(passed + " passed, " + failed + " failed" + (failed > 0 ? " — the campaign fails its checks" : ""));
    const text = runs.size === 0 ? "no checks judged yet" : held.campaign + ": " + (texts.length ? texts.join("; ") : "judged as each run ends");
    $("verdict-summary").textContent = text;
    $("verdict-summary").className = failed + underWay.failed > 0 || unjudged.length > 0 ? "bad" : "about";
    body.dataset.verdictsFailed = String(failed);
    body.dataset.verdictsPassed = String(passed);
    body.dataset.liveRun = underWay.run;
    body.dataset.liveFailed = String(underWay.failed);
    body.dataset.livePending = String(underWay.pending);
    body.dataset.verdictsDirs = [...runs.values()].map((v) => v.dir || "").join(",");
    body.dataset.verdictsUnjudged = unjudged.join(",");
  }

  function runStart(m) {
    own(keyOf(m), m.campaign);
    runs.set(m.run, { dir: m.dir, state: "running", checks: null, final: false });
    render();
  }
  function runEnd(m) {
    own(keyOf(m), m.campaign);
    runs.set(m.run, { dir: m.dir, state: m.outcome, reason: m.reason, stop_utc: new Date().toISOString(), checks: checksOf(m), final: true });
    render();
  }
  // A status message while a run goes on: its checks as they stand. Only for a run still under
  // way here: a status read before its run_end may arrive after it, and the final verdicts stay.
  function live(m) {
    const c = m.checks;
    if (!c || !Array.isArray(c.results) || !c.run || m.state === "idle") return;
    own(keyOf(m), m.campaign);
    const v = runs.get(c.run);
    if (v && v.state !== "running" && (!m.run_dir || v.dir === m.run_dir)) return;
    runs.set(c.run, { dir: m.run_dir || (v && v.dir) || "", state: "running", checks: c, final: false });
    render();
  }
  // How the last run ended (the status's last_run): a run shown as under way that ended without
  // its run_end here (the server died, and the restarted one found it interrupted) is marked so; a
  // newer run than any shown replaces the panel.
  function lastRun(r) {
    if (!r || !r.dir) return;
    for (const [run, v] of runs) {
      if (v.dir !== r.dir) continue;
      if (v.state === "running") {
        runs.set(run, { ...v, state: r.outcome, reason: r.reason, stop_utc: r.stop_utc });
        render();
      }
      return;
    }
    if ([...runs.values()].some((v) => (v.dir || "") >= r.dir)) return;  // an older run than those shown
    own("run:" + r.dir, r.campaign);
    runs.set(r.run, { dir: r.dir, state: r.outcome, reason: r.reason, stop_utc: r.stop_utc, checks: null, final: true });
    render();
  }
  // The last campaign's verdicts, for a page that was not open when its runs ended (GET /api/status).
  function fromStatus(s) {
    if (s.state !== "idle") return;
    const last = s.last;
    const lastRunIsIts = last && Array.isArray(last.runs) && (!s.last_run || last.runs.some((r) => r.dir === s.last_run.dir));
    if (lastRunIsIts && keyOf(last) !== held.key) {
      own(keyOf(last), last.campaign);
      for (const r of last.runs) runs.set(r.run, { dir: r.dir, state: r.outcome, reason: r.reason, checks: checksOf(r), final: true });
      render();
    }
    lastRun(s.last_run);
  }

  return { runStart, runEnd, fromStatus, live, lastRun };
};
