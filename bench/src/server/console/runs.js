// The operator console's recorded runs (inlined before console.js): each with its outcome and
// duration, its report, its files and its analyses against a plant model (Compare / Diagnose,
// followed live while they run); two runs ticked open side by side in one report
// (GET /api/report?runs=A,B, the CLI's `hilbench report A B`).
"use strict";
window.hilRuns = function hilRuns({ $, api, act, withToken, showMessage, ApiRefusal }) {
  const fmt = (v, digits) => (typeof v === "number" ? v.toFixed(digits) : "–");
  function link(href, text, newTab) {
    const a = document.createElement("a");
    a.href = withToken(href);
    a.textContent = text;
    if (newTab) a.target = "_blank";
    return a;
  }
  function refreshRuns() {
    return loadRuns().catch((e) => showMessage("cannot list runs: " + e.message, false));
  }

  let models = [];
  const analysesOf = new Map();  // run id -> its analyses, as last listed
  const analysisPolls = new Map();  // run id -> timer while one of its analyses is queued or running
  const kAnalysedRuns = 20;  // the newest runs whose analyses are listed

  async function loadModels() {
    models = (await api("GET", "/api/models")).models.filter((m) => !m.error);
    for (const sel of document.querySelectorAll("#runs-table select.model")) fillModels(sel);
  }
  // The run's own plant (its recorded snapshot's, GET /api/runs "plant") first, else nominal: a run
  // compared against another plant than it ran on reads as a bad fit (soak_random: 18 % against
  // nominal, 91 % against its own constant_volume).
  function fillModels(sel) {
    const own = sel.dataset.plant && models.some((m) => m.name === sel.dataset.plant) ? sel.dataset.plant : "nominal";
    const keep = sel.value || own;
    sel.replaceChildren(...models.map((m) => new Option(m.name + (m.name === sel.dataset.plant ? " (the run's plant)" : ""), m.name, false,
      m.name === keep)));
  }

  function renderAnalyses(runId) {
    const ul = document.querySelector(`#runs-table tr[data-run="${CSS.escape(runId)}"] ul.analyses`);
    if (!ul) return;
    ul.replaceChildren(...(analysesOf.get(runId) || []).map((a) => {
      const li = document.createElement("li");
      li.dataset.id = a.id;
      li.dataset.kind = a.kind || "";
      li.dataset.state = a.state || "";
      const what = (a.kind || "?") + " vs " + (a.model || "?") + ": ";
      if (a.state === "done") {
        const r = a.result || {};
        // The fit beside what the sensor's noise allows at best, and the verdict in words.
        const floor = typeof r.noise_floor_fit_pct === "number" ? " (noise floor " + fmt(r.noise_floor_fit_pct, 1) + " %)" : "";
        const figure = a.kind === "compare" ? "fit " + fmt(r.fit_pct, 1) + " %" + floor : String(r.verdict || "").replaceAll("_", " ") +
          (r.added && r.added.length ? " (" + r.added.map((x) => x.effect).join(", ") + ")" : "") +
          (typeof r.fit_after_pct === "number" ? ": fit " + fmt(r.fit_before_pct, 1) + " → " + fmt(r.fit_after_pct, 1) + " %" + floor : "");
        const open = link(a.report, "report", true);
        open.className = "analysis-report";
        li.append(what + figure + " ", open);
      } else if (a.state === "failed") {
        li.className = "bad";
        li.append(what + "failed: " + (a.error || "?"));
      } else {
        li.append(what + a.state + (typeof a.progress === "number" ? " " + Math.round(100 * a.progress) + " %" : "") + "…");
      }
      return li;
    }));
  }

  async function refreshAnalyses(runId) {
    clearTimeout(analysisPolls.get(runId));
    analysisPolls.delete(runId);
    try {
      const list = (await api("GET", "/api/runs/" + encodeURIComponent(runId) + "/analyses")).analyses;
      analysesOf.set(runId, list);
      renderAnalyses(runId);
      // Followed live while one is queued or running.
      if (list.some((a) => a.state === "queued" || a.state === "running"))
        analysisPolls.set(runId, setTimeout(() => refreshAnalyses(runId), 700));
    } catch (e) {
      if (!(e instanceof ApiRefusal) && !(e instanceof TypeError)) throw e;  // the next refresh tries again
    }
  }

  async function analyse(runId, kind, model) {
    const reply = await act(kind + " of " + runId + " against " + model, "POST", "/api/runs/" + encodeURIComponent(runId) + "/analyses",
      { kind, model });
    if (reply) await refreshAnalyses(runId);
  }

  function analysisCell(r) {
    const td = document.createElement("td");
    td.className = "analysis";
    if (!r.outcome || r.outcome === "running") return td;
    const sel = document.createElement("select");
    sel.className = "model";
    sel.title = "the plant model (configs/plant)";
    if (r.plant) sel.dataset.plant = r.plant;
    fillModels(sel);
    const buttons = ["compare", "diagnose"].map((kind) => {
      const b = document.createElement("button");
      b.type = "button";
      b.className = "analyse";
      b.dataset.kind = kind;
      b.textContent = kind === "compare" ? "Compare" : "Diagnose";
      b.title = kind === "compare" ? "replay the run through the model: where does it fail?" : "which missing effect explains the misfit?";
      b.addEventListener("click", () => analyse(r.id, kind, sel.value));
      return b;
    });
    const ul = document.createElement("ul");
    ul.className = "analyses";
    td.append(sel, ...buttons, ul);
    return td;
  }

  // A finished run's wall-clock duration from run.json's start and stop (h:mm:ss).
  function duration(r) {
    const t0 = Date.parse(r.start_utc || ""), t1 = Date.parse(r.stop_utc || "");
    if (!(t1 >= t0)) return r.outcome === "running" ? "running" : "–";
    const s = Math.round((t1 - t0) / 1000);
    const two = (v) => String(v).padStart(2, "0");
    return (s >= 3600 ? Math.floor(s / 3600) + ":" + two(Math.floor(s / 60) % 60) : String(Math.floor(s / 60))) + ":" + two(s % 60);
  }

  // Two runs side by side: each run's own report (made on demand, ?wait=1) in one of two frames.
  let picked = [];
  $("side-by-side").addEventListener("click", () => {
    if (picked.length !== 2) return;
    const frames = picked.map((id) => {
      const cell = document.createElement("div");
      cell.className = "side";
      const head = document.createElement("div");
      head.className = "about";
      head.append(id + " ", link("/api/runs/" + encodeURIComponent(id) + "/report.html", "open alone", true));
      const frame = document.createElement("iframe");
      frame.title = "report of " + id;
      frame.dataset.run = id;
      frame.src = withToken("/api/runs/" + encodeURIComponent(id) + "/report.html?wait=1");
      cell.append(head, frame);
      return cell;
    });
    $("side-view").replaceChildren(...frames);
    $("side-panel").hidden = false;
  });
  $("side-close").addEventListener("click", () => {
    $("side-panel").hidden = true;
    $("side-view").replaceChildren();
  });

  async function loadRuns() {
    const reply = await api("GET", "/api/runs");
    const tbody = $("runs-table").querySelector("tbody");
    const shown = reply.runs.slice(0, 200);
    tbody.replaceChildren(...shown.map((r) => {
      const tr = document.createElement("tr");
      tr.dataset.run = r.id;
      const cells = [r.id, (r.campaign || "?") + " / " + (r.run || "?"), r.outcome || r.error || "?", r.reason || "", duration(r)].map((text) => {
        const td = document.createElement("td");
        td.textContent = text;
        return td;
      });
      cells[2].className = "outcome outcome-" + (r.outcome || "error");
      cells[4].className = "num duration";
      // Ticked for the side-by-side view (two runs).
      const pick = document.createElement("input");
      pick.type = "checkbox";
      pick.className = "pick";
      pick.value = r.id;
      pick.title = "tick two runs, then Side by side";
      pick.disabled = !r.outcome || r.outcome === "running";
      pick.checked = picked.includes(r.id);
      pick.addEventListener("change", () => {
        picked = pick.checked ? [...picked.filter((x) => x !== r.id), r.id].slice(-2) : picked.filter((x) => x !== r.id);
        for (const box of $("runs-table").querySelectorAll("input.pick")) box.checked = picked.includes(box.value);
        $("side-by-side").disabled = picked.length !== 2;
      });
      cells[0].prepend(pick, " ");
      const files = document.createElement("td");
      const base = "/api/runs/" + encodeURIComponent(r.id);
      if (r.outcome && r.outcome !== "running") {
        const report = link(base + "/report.html", "report", true);
        report.className = "report";
        files.append(report);
      }
      for (const f of ["telemetry.csv", "events.jsonl", "run.json"]) files.append(link(base + "/" + f, f, false));
      tr.append(...cells, files, analysisCell(r));
      return tr;
    }));
    for (const r of shown.slice(0, kAnalysedRuns)) {
      renderAnalyses(r.id);
      if (r.outcome && r.outcome !== "running") refreshAnalyses(r.id);
    }
  }
  $("runs-refresh").addEventListener("click", refreshRuns);

  return { refresh: refreshRuns, loadModels };
};
