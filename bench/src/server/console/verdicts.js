// The operator console's verdict panel (inlined before console.js): the campaign's checks
// (`checks:` in its YAML, judged by the server with the one evaluator of `hilbench sim`,
// server/run_verdicts.hpp) per run, as pass / FAIL / skipped with the value against its limit. They
// arrive on the telemetry WebSocket in each run's run_end message, so a run's verdicts show the
// moment it ends, while the campaign's later runs go on; a page opened later takes the last
// campaign's from the status (last.runs[].checks). A run under way is listed as being judged.
// For tests: body data-verdicts-failed / data-verdicts-passed (counts shown); each row data-run,
// data-check, data-verdict.
"use strict";
window.hilVerdicts = function hilVerdicts({ $, body }) {
  let campaign = "";
  const runs = new Map();  // run name -> { state: "running" | outcome, checks: {passed, failed, skipped, results} | null }
  body.dataset.verdictsFailed = "0";
  body.dataset.verdictsPassed = "0";

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
    for (const [run, v] of runs) {
      if (!v.checks) {
        const tr = document.createElement("tr");
        tr.dataset.run = run;
        tr.dataset.verdict = v.state === "running" ? "pending" : "none";
        const td = document.createElement("td");
        td.colSpan = 4;
        td.textContent = run + ": " + (v.state === "running" ? "running; its checks are judged when it ends" : v.state + ", no checks");
        td.className = "about";
        tr.append(td);
        rowsOut.push(tr);
        continue;
      }
      for (const r of v.checks.results || []) {
        const tr = document.createElement("tr");
        tr.dataset.run = run;
        tr.dataset.check = r.check;
        tr.dataset.verdict = r.verdict;
        if (r.verdict === "fail") ++failed;
        if (r.verdict === "pass") ++passed;
        tr.title = r.message || "";  // what was measured against what, or why it was skipped
        const cells = [run + " / " + r.check, r.verdict === "fail" ? "FAIL" : r.verdict, num(r.value), limit(r)].map((t) => {
          const td = document.createElement("td");
          td.textContent = t;
          return td;
        });
        cells[1].className = "verdict verdict-" + r.verdict;
        cells[2].className = cells[3].className = "num";
        tr.append(...cells);
        rowsOut.push(tr);
      }
    }
    $("verdict-list").replaceChildren(...rowsOut);
    const judged = [...runs.values()].some((v) => v.checks);
    $("verdict-summary").textContent = runs.size === 0 ? "no checks judged yet" : !judged ? campaign + ": judged as each run ends" :
      campaign + ": " + passed + " passed, " + failed + " failed" + (failed > 0 ? " — the campaign fails its checks" : "");
    $("verdict-summary").className = failed > 0 ? "bad" : "about";
    body.dataset.verdictsFailed = String(failed);
    body.dataset.verdictsPassed = String(passed);
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
  // The last campaign's verdicts, for a page that was not open when its runs ended.
  function fromStatus(s) {
    if (runs.size > 0 || s.state !== "idle" || !s.last || !Array.isArray(s.last.runs)) return;
    campaign = s.last.campaign || "";
    for (const r of s.last.runs) runs.set(r.run, { state: r.outcome, checks: r.checks && Array.isArray(r.checks.results) ? r.checks : null });
    if (runs.size > 0) render();
  }

  return { runStart, runEnd, fromStatus };
};
