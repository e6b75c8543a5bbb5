// The operator console's verdict panel (inlined before console.js): the campaign's checks
// (`checks:` in its YAML, judged by the server with the one evaluator of `hilbench sim`,
// server/run_verdicts.hpp) per run, as pass / FAIL / skipped with the value against its limit. They
// arrive on the telemetry WebSocket in each run's run_end message, so a run's verdicts show the
// moment it ends, while the campaign's later runs go on; a page opened later takes the last
// campaign's from the status (last.runs[].checks). While a run goes on, the stream's status
// messages carry its checks as they stand (live: a signal check that failed is FAIL at once, one
// whose window closed within its limit "pass so far", one none of whose windows can open again
// decided, the rest pending; a metric of the whole run "pending until the end"); its run_end
// replaces them with the final ones.
// For tests: body data-verdicts-failed / data-verdicts-passed (counts of ended runs' verdicts),
// data-live-run / data-live-failed / data-live-pending (the run under way's); each row data-run,
// data-check, data-verdict (pending | passing | pass | fail | skipped) and data-live ("1" while
// the run goes on).
"use strict";
window.hilVerdicts = function hilVerdicts({ $, body }) {
  let campaign = "";
  // run name -> { state: "running" | outcome, checks: {passed, failed, skipped, results} | live {run, t_s, results} | null }
  const runs = new Map();
  body.dataset.verdictsFailed = "0";
  body.dataset.verdictsPassed = "0";
  body.dataset.liveRun = "";
  body.dataset.liveFailed = "0";
  body.dataset.livePending = "0";
  const shown = { fail: "FAIL", passing: "pass so far" };

  const num = (v) => (typeof v === "number" && isFinite(v) ? String(+v.toPrecision(4)) : "–");
  function limit(r) {
    const parts = [];
    if (typeof r.min === "number") parts.push("≥ " + num(r.min));
    if (typeof r.max === "number") parts.push("≤ " + num(r.max));
    return parts.join(" and ") || "–";
  }

  function render() {
    const rowsOut = [];
    let failed = 0, passed = 0;
    const underWay = { run: "", failed: 0, passing: 0, pending: 0, t_s: null };
    for (const [run, v] of runs) {
      const live = v.state === "running";
      if (!v.checks) {
        const tr = document.createElement("tr");
        tr.dataset.run = run;
        tr.dataset.verdict = v.state === "running" ? "pending" : "none";
        const td = document.createElement("td");
        td.colSpan = 4;
        td.textContent = run + ": " + (v.state === "running" ? "running; its checks show as they are judged" : v.state + ", no checks");
        td.className = "about";
        tr.append(td);
        rowsOut.push(tr);
        continue;
      }
      if (live) {
        underWay.run = run;
        underWay.t_s = v.checks.t_s;
      }
      for (const r of v.checks.results || []) {
        const tr = document.createElement("tr");
        tr.dataset.run = run;
        tr.dataset.check = r.check;
        tr.dataset.verdict = r.verdict;
        tr.dataset.live = live ? "1" : "0";
        if (live) {
          if (r.verdict === "fail") ++underWay.failed;
          else if (r.verdict === "passing" || r.verdict === "pass") ++underWay.passing;
          else if (r.verdict === "pending") ++underWay.pending;
        } else {
          if (r.verdict === "fail") ++failed;
          if (r.verdict === "pass") ++passed;
        }
        tr.title = r.message || "";  // what was measured against what, or why it was skipped
        const verdict = shown[r.verdict] || (r.verdict === "pending" && r.at_end ? "pending until the end" : r.verdict);
        const cells = [run + " / " + r.check, verdict, num(r.value), limit(r)].map((t) => {
          const td = document.createElement("td");
          td.textContent = t;
          return td;
        });
        cells[1].className = "verdict verdict-" + (r.verdict === "passing" ? "pass" : r.verdict);
        cells[2].className = cells[3].className = "num";
        tr.append(...cells);
        rowsOut.push(tr);
      }
    }
    $("verdict-list").replaceChildren(...rowsOut);
    const judged = [...runs.values()].some((v) => v.checks && v.state !== "running");
    let text = runs.size === 0 ? "no checks judged yet" : !judged ? campaign + ": judged as each run ends" :
      campaign + ": " + passed + " passed, " + failed + " failed" + (failed > 0 ? " — the campaign fails its checks" : "");
    if (underWay.run) {
      text = (judged ? text + "; " : campaign + ": ") + underWay.run + " under way" + (typeof underWay.t_s === "number" ? " at " + underWay.t_s.toFixed(1) + " s" : "") +
        ": " + underWay.failed + " failed, " + underWay.passing + " pass so far, " + underWay.pending + " pending (metrics of the whole run are judged at its end)";
    }
    $("verdict-summary").textContent = text;
    $("verdict-summary").className = failed + underWay.failed > 0 ? "bad" : "about";
    body.dataset.verdictsFailed = String(failed);
    body.dataset.verdictsPassed = String(passed);
    body.dataset.liveRun = underWay.run;
    body.dataset.liveFailed = String(underWay.failed);
    body.dataset.livePending = String(underWay.pending);
  }

  function runStart(m) {
    if (m.campaign !== campaign || runs.has(m.run)) {  // a new campaign (or the same one again)
      if (m.campaign !== campaign || runs.get(m.run).state !== "running") runs.clear();
      campaign = m.campaign;
    }
    runs.set(m.run, { state: "running", checks: null });
    render();
  }
  function runEnd(m) {
    if (m.campaign && m.campaign !== campaign) {
      runs.clear();
      campaign = m.campaign;
    }
    runs.set(m.run, { state: m.outcome, checks: m.checks && Array.isArray(m.checks.results) ? m.checks : null });
    render();
  }
  // A status message while a run goes on: its checks as they stand. Only for a run still under
  // way here: a status read before its run_end may arrive after it, and the final verdicts stay.
  function live(m) {
    const c = m.checks;
    if (!c || !Array.isArray(c.results) || !c.run || m.state === "idle") return;
    if (m.campaign && m.campaign !== campaign) {
      runs.clear();
      campaign = m.campaign;
    }
    const v = runs.get(c.run);
    if (v && v.state !== "running") return;
    runs.set(c.run, { state: "running", checks: c });
    render();
  }
  // The last campaign's verdicts, for a page that was not open when its runs ended.
  function fromStatus(s) {
    if (runs.size > 0 || s.state !== "idle" || !s.last || !Array.isArray(s.last.runs)) return;
    campaign = s.last.campaign || "";
    for (const r of s.last.runs) runs.set(r.run, { state: r.outcome, checks: r.checks && Array.isArray(r.checks.results) ? r.checks : null });
    if (runs.size > 0) render();
  }

  return { runStart, runEnd, fromStatus, live };
};
