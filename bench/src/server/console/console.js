// The operator console of `hilbench serve` (GET /): live plots from the telemetry WebSocket,
// loop health from /api/status, the run's events, controls and the recorded runs. Plain script
// (no modules, no network beyond this server); plotting is Dygraph (Debian's libjs-dygraphs,
// inlined before this script). For tests the body carries data-frames-rendered (plot redraws),
// data-points (rows held) and data-console-errors (errors caught here), and window.hilConsole
// gives the plots and the buffer.
"use strict";
(() => {
  const body = document.body;
  const $ = (id) => document.getElementById(id);
  const W = window.hilWords;

  // ---------------------------------------------------------------------------------------------
  // Errors: counted where a test can see them, and shown.
  let errorCount = 0;
  body.dataset.consoleErrors = "0";
  function noteError(text) {
    body.dataset.consoleErrors = String(++errorCount);
    showMessage("console error: " + text, false);
  }
  window.addEventListener("error", (e) => noteError(String(e.message)));
  window.addEventListener("unhandledrejection", (e) => noteError(String(e.reason && e.reason.message ? e.reason.message : e.reason)));

  // The last message, in green (ok: true), yellow (ok: "warn": answered, but nothing was done) or
  // red; it clears itself after kMessageMs unless sticky (an abort not delivered), a restored link
  // clears it (what the lost link made is stale then), and another run's start clears one about a
  // run (ofRun: an abort's answer, an injection's).
  const kMessageMs = 10000;
  let messageTimer = null;
  function showMessage(text, ok, sticky, ofRun) {
    const m = $("message");
    m.dataset.ofRun = ofRun ? "1" : "";
    m.textContent = text;
    m.dataset.kind = ok === "warn" ? "warn" : ok ? "ok" : "bad";
    m.className = "message " + m.dataset.kind;
    m.hidden = false;
    clearTimeout(messageTimer);
    if (!sticky) messageTimer = setTimeout(() => (m.hidden = true), kMessageMs);
  }
  function clearMessages() {
    clearTimeout(messageTimer);
    $("message").hidden = true;
  }

  // ---------------------------------------------------------------------------------------------
  // The token: from ?token=T once, then kept for this tab only; sent on every call.
  const params = new URLSearchParams(location.search);
  let token = sessionStorage.getItem("hilbench.token") || "";
  if (params.has("token")) {
    token = params.get("token");
    sessionStorage.setItem("hilbench.token", token);
    history.replaceState(null, "", location.pathname);  // out of the address bar and the history
  }
  const withToken = (path) => (token ? path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : path);

  class ApiRefusal extends Error {
    constructor(status, reply) {
      super(reply && reply.error ? reply.error + (reply.detail ? ": " + reply.detail : "") : "HTTP " + status);
      this.status = status;
    }
  }

  async function api(method, path, payload, signal) {
    const headers = {};
    if (token) headers.Authorization = "Bearer " + token;
    if (payload !== undefined) headers["Content-Type"] = "application/json";
    const res = await fetch(path, { method, headers, body: payload === undefined ? undefined : JSON.stringify(payload), signal });
    const text = await res.text();
    let reply = null;
    try {
      reply = JSON.parse(text);
    } catch (e) {
      reply = null;
    }
    if (!res.ok) throw new ApiRefusal(res.status, reply);
    return reply;
  }
  async function apiText(path) {
    const res = await fetch(path, { headers: token ? { Authorization: "Bearer " + token } : {} });
    if (!res.ok) throw new ApiRefusal(res.status, null);
    return res.text();
  }

  // What the API refuses is shown with its reason (and the action it answered).
  async function act(what, method, path, payload) {
    try {
      const reply = await api(method, path, payload);
      showMessage(what + ": accepted", true);
      return reply;
    } catch (e) {
      if (e instanceof TypeError) {  // no answer: the server is unreachable
        showMessage(what + ": NOT delivered (the server did not answer: " + e.message + "); nothing was done", false);
        events.add("refused", what + ": not delivered (no answer from the server)", "refused");
        return null;
      }
      if (!(e instanceof ApiRefusal)) throw e;
      showMessage(what + ": refused (" + e.status + ") " + e.message, false);
      events.add("refused", what + ": " + e.message, "refused");
      return null;
    }
  }

  // The link and the safety state (link.js), the events (events.js).
  const linkState = window.hilLink({ $, body, api, ApiRefusal, showMessage, clearMessages, onState: (state, m) => reflectState(state, m) });
  const live = window.hilPlots({ $, body, palette: window.hilPalette });
  const events = window.hilEvents({ $, body, apiText, ApiRefusal, onMarks: (list) => live.setMarks(list) });
  const verdicts = window.hilVerdicts({ $, body });
  const runsList = window.hilRuns({ $, api, act, withToken, showMessage, ApiRefusal });
  const refreshRuns = () => runsList.refresh();
  let droppedTotal = 0;


  let ws = null;
  function connect() {
    const scheme = location.protocol === "https:" ? "wss://" : "ws://";
    ws = new WebSocket(scheme + location.host + withToken("/api/telemetry?rate_hz=30"));
    ws.onopen = () => linkState.opened();
    let reconnecting = false;
    const again = () => {
      if (reconnecting) return;
      reconnecting = true;
      linkState.closed();
      setTimeout(connect, 1000);
    };
    ws.onclose = again;
    ws.onerror = again;
    ws.onmessage = (e) => {
      linkState.heard();
      let m;
      try {
        m = JSON.parse(e.data);
      } catch (err) {
        return;
      }
      if (m.type === "row") return live.addRow(m);
      if (m.type === "status") {
        if (m.run_dir && m.state !== "idle") runShown(m.run_dir, m);
        linkState.status(m);
        verdicts.live(m);
        if (m.state === "idle") lastRunShown(m.last_run);
      } else if (m.type === "run_start") {
        runShown(m.dir, m);
        verdicts.runStart(m);
      } else if (m.type === "run_end") {
        linkState.runEnd(m);
        verdicts.runEnd(m);
        plotsOf(m.dir, { ...m, stop_utc: new Date().toISOString() });
        events.add("run_end", W.ended(m, { noCampaign: true }), m.outcome === "completed" ? "" : "trip");
        events.follow(m.dir);
        refreshRuns();
      } else if (m.type === "campaign_end") {
        events.add("campaign_end", "campaign " + m.campaign + ": " + m.outcome + (m.reason ? " (" + m.reason + ")" : ""), "");
        refreshRuns();
      } else if (m.type === "dropped") {
        droppedTotal = m.total;
        events.add("dropped", W.plural(m.messages, "telemetry message") + " dropped (" + m.why + ")", "");
      }
    };
  }

  // ---------------------------------------------------------------------------------------------
  // Every panel belongs to one run. A run seen start (run_start, or a status naming another run
  // folder): the plots, events, checks and latch of the one before are cleared or marked as the
  // previous run's, and messages about it go. Idle: the last run's end (status last_run, also a
  // run a dead server left, marked interrupted by the restarted one) says what became of the run
  // the panels show.
  let shownDir = "";
  let lastFollowed = "";
  function runShown(dir, m) {
    if (!dir || dir === shownDir) return;
    const first = shownDir === "";
    shownDir = dir;
    if (!first || m.type === "run_start") live.clear();
    if (!first && $("message").dataset.ofRun === "1" && !linkState.aborting()) clearMessages();
    linkState.newRun(dir);
    events.setCurrent(dir);
    plotsOf(dir, m);
  }
  function lastRunShown(r) {
    if (!r || !r.dir) return;
    if (shownDir === "" || shownDir === r.dir) {
      shownDir = r.dir;
      events.setCurrent(r.dir);
      plotsOf(r.dir, r);
      if (lastFollowed !== r.dir + "|" + r.outcome) {  // its end (and an interrupted run's "interrupted" event) once
        lastFollowed = r.dir + "|" + r.outcome;
        events.follow(r.dir);
      }
    }
    verdicts.lastRun(r);
  }
  // The plots' caption: whose telemetry it is, and how that run ended.
  function plotsOf(dir, m) {
    if (dir !== shownDir) return;
    if (live.counts().held === 0 && !(m.outcome === "running" || !m.outcome)) return $("plots-run").replaceChildren();  // nothing of it drawn
    const ended = m.outcome && m.outcome !== "running";
    $("plots-run").textContent = ended ? W.ended(m) : W.run(m.run) + " of " + (m.campaign || "?") + " under way";
    $("plots-run").className = "plots-run" + (ended && m.outcome !== "completed" ? " bad" : "");
    $("plots-run").dataset.run = dir;
    $("plots-run").dataset.outcome = ended ? m.outcome : "running";
  }

  // ---------------------------------------------------------------------------------------------
  // Status, about once a second: the header, loop health, interlocks.
  const fmt = (v, digits) => (typeof v === "number" ? v.toFixed(digits) : "–");
  const latency = (h) => (h ? fmt(h.p50_us, 1) + " / " + fmt(h.p99_us, 1) + " / " + fmt(h.max_us, 1) + " µs" : "–");
  let lastState = "";

  // The header and the controls follow the stream's status messages (link.js): what runs, and
  // only the controls that can act enabled. "unknown": the link is lost.
  const injectButtons = ["inject-gap", "inject-programme", "inject-sensor", "inject-drive", "inject-clear"];
  let shownCampaign = "";
  function reflectState(state, m) {
    const live = state !== "unknown";
    const active = state === "running" || state === "safe" || state === "tripped" || state === "starting";
    $("start").disabled = !live || state !== "idle";
    $("stop").disabled = !live || !active;
    // ABORT stays live whenever the bench may be running: also with the link lost (it then says
    // it was not delivered, and retries), and while an abort is being retried.
    $("abort").disabled = live && !active && !linkState.aborting();
    for (const id of injectButtons) $(id).disabled = state !== "running";
    for (const id of ["campaign", "rig"]) $(id).disabled = active;
    for (const box of $("runs-choice").querySelectorAll("input")) box.disabled = active;
    if (!m) return;
    if (state === "idle") {
      // How the last run ended (completed / aborted / interrupted, when and why), from the server's record.
      const r = m.last_run;
      $("what").textContent = r ? "no run under way · last: " + W.ended(r) : "no run under way";
      $("what").title = $("what").textContent;
      $("what").dataset.run = r ? r.dir : "";
      $("what").dataset.outcome = r ? r.outcome : "";
      $("progress").value = 0;
      $("run-time").textContent = "";
      shownCampaign = "";
      return;
    }
    // The run's time apart, never cut off (on a phone what runs wraps below it).
    $("run-time").textContent = "t " + fmt(m.run_t_s, 1) + " / " + fmt(m.duration_s, 0) + " s";
    $("what").textContent = (m.campaign || "?") + " · " + W.run(m.run) + " (" + ((m.run_index ?? 0) + 1) + " of " + (m.runs_total ?? "?") + ") on rig " +
      W.quoted(m.rig);
    $("what").title = $("what").textContent;
    $("what").dataset.run = m.run_dir || "";
    $("what").dataset.outcome = "running";
    $("progress").value = m.fraction || 0;
    // The controls show what runs (started here, by another console or through the API).
    const key = m.campaign + "|" + m.rig + "|" + (m.runs || []).join(",");
    if (key !== shownCampaign && campaigns.some((c) => c.name === m.campaign)) {
      shownCampaign = key;
      $("campaign").value = m.campaign;
      renderRunsChoice();
      if (rigs.some((r) => r.name === m.rig)) $("rig").value = m.rig;
      renderRigAbout();
      if (Array.isArray(m.runs)) for (const box of $("runs-choice").querySelectorAll("input")) box.checked = m.runs.includes(box.value);
      for (const box of $("runs-choice").querySelectorAll("input")) box.disabled = true;
    }
  }

  function renderStatus(s) {
    const state = s.state || "idle";
    verdicts.fromStatus(s);

    const dl = $("health-list");
    const items = [];
    const loop = s.loop;
    const tel = s.telemetry || {};
    if (loop) {
      items.push(["scheduling", W.realtime(loop.sched) + (loop.memory_locked ? "; memory locked" : "; memory not locked"), false, W.kRealtimeTip]);
      if (loop.rt_warning) items.push(["real-time warning", loop.rt_warning, true]);
      items.push(["periods", loop.periods, false]);
      items.push(["wake-up latency p50/p99/max", latency(loop.wake_latency_us), false]);
      items.push(["compute time p50/p99/max", latency(loop.compute_us), false]);
      items.push(["rig read / write p99", fmt(loop.rig_read_us && loop.rig_read_us.p99_us, 1) + " / " + fmt(loop.rig_write_us && loop.rig_write_us.p99_us, 1) + " µs", false]);
      items.push(["overruns", loop.overruns, loop.overruns > 0]);
      items.push(["skipped deadlines", loop.skipped_deadlines, loop.skipped_deadlines > 0]);
      items.push(["missed reads", loop.missed_reads, loop.missed_reads > 0]);
      items.push(["limited periods", loop.limited_periods, false]);
      items.push(["rows written / lost / unwritten", (tel.rows_written ?? "–") + " / " + (tel.rows_lost ?? "–") + " / " + (tel.rows_unwritten ?? "–"),
        tel.rows_lost > 0 || tel.rows_unwritten > 0]);
      if (typeof tel.ring_capacity === "number" && tel.ring_capacity > 0)
        items.push(["telemetry ring fill", tel.ring_fill + " of " + tel.ring_capacity + " rows (" + (100 * tel.ring_fill / tel.ring_capacity).toFixed(1) + " %)",
          tel.ring_fill > tel.ring_capacity / 2]);
      if (tel.write_error) items.push(["write error", tel.write_error, true]);
      items.push(["events lost", tel.events_lost ?? "–", tel.events_lost > 0]);
    }
    const counts = live.counts();
    items.push(["live view: rows received / held", counts.received + " / " + counts.held, false]);
    items.push(["live view: messages dropped", droppedTotal, droppedTotal > 0]);
    dl.replaceChildren(...items.flatMap(([k, v, bad, tip]) => {
      const dt = document.createElement("dt");
      dt.textContent = k;
      if (tip) dt.title = tip;
      const dd = document.createElement("dd");
      dd.textContent = String(v);
      if (bad) dd.className = "bad";
      return [dt, dd];
    }));

    const il = $("interlocks");
    if (state === "idle") {
      il.textContent = "no campaign running";
      il.className = "about";  // not the last run's red
    } else {
      const safety = s.safety || {};
      const faults = (s.faults || []).map((f) => Object.entries(f).map(([k, v]) => k + " " + (typeof v === "number" ? +v.toFixed(4) : v)).join(" ")).join("; ");
      il.textContent = (safety.safe_state ? "SAFE STATE" + (safety.trip ? " (trip: " + safety.trip + ")" : "") : "interlocks armed, no trip") +
        " · faults: " + (faults || "none");
      il.className = safety.safe_state ? "about bad" : "about";
    }

    if (state !== "idle" && s.run_dir) {
      runShown(s.run_dir, s);
      events.follow(s.run_dir);
    }
    if (state !== lastState && (state === "idle" || lastState === "")) refreshRuns();
    lastState = state;
  }

  async function pollStatus() {
    try {
      renderStatus(await api("GET", "/api/status"));
    } catch (e) {
      if (!(e instanceof ApiRefusal) && !(e instanceof TypeError)) throw e;  // unreachable: the link's banner says so
    } finally {
      setTimeout(pollStatus, 1000);
    }
  }

  // ---------------------------------------------------------------------------------------------
  // Controls.
  let campaigns = [];
  function renderRunsChoice() {
    const c = campaigns.find((x) => x.name === $("campaign").value);
    const fs = $("runs-choice");
    fs.replaceChildren(fs.firstElementChild);
    $("campaign-about").textContent = c ? (c.error ? "cannot load: " + c.error : (c.description || "") + " · " + c.duration_s + " s per run, period " + c.period_ms + " ms") : "";
    for (const r of (c && c.runs) || []) {
      const label = document.createElement("label");
      const box = document.createElement("input");
      box.type = "checkbox";
      box.checked = true;
      box.value = r;
      label.append(box, " " + r);
      fs.append(label);
    }
  }

  // The chosen rig's interlocks, and the server's warning about it (a real drive without the
  // following-error interlock), shown before Start is pressed: that is when an operator decides.
  let rigs = [];
  function renderRigAbout() {
    const r = rigs.find((x) => x.name === $("rig").value);
    const about = $("rig-about");
    const warning = document.createElement("span");
    warning.className = "bad";
    if (!r) {
      about.replaceChildren();
    } else if (r.error) {
      warning.textContent = "cannot load: " + r.error;
      about.replaceChildren(warning);
    } else {
      const fe = r.following_error;
      const text = (r.description || r.kind || "") + (fe ? " · following-error interlock " + fe.max_deg + " deg for " + fe.time_ms + " ms" : "");
      warning.textContent = r.warning ? "WARNING: " + r.warning : "";
      about.replaceChildren(text, ...(r.warning ? [document.createElement("br"), warning] : []));
    }
  }

  async function loadChoices() {
    const [c, r] = await Promise.all([api("GET", "/api/campaigns"), api("GET", "/api/rigs")]);
    campaigns = c.campaigns;
    rigs = r.rigs;
    $("campaign").replaceChildren(...campaigns.map((x) => new Option(x.name + (x.error ? " (invalid)" : ""), x.name)));
    $("rig").replaceChildren(...rigs.map((x) => new Option(x.name + (x.kind ? " (" + x.kind + ")" : "") +
      (x.error ? " (invalid)" : x.warning ? " (no following-error interlock)" : ""), x.name, x.name === "sim", x.name === "sim")));
    renderRunsChoice();
    renderRigAbout();
  }
  $("campaign").addEventListener("change", renderRunsChoice);
  $("rig").addEventListener("change", renderRigAbout);

  $("start").addEventListener("click", async () => {
    const boxes = [...$("runs-choice").querySelectorAll("input[type=checkbox]")];
    const chosen = boxes.filter((b) => b.checked).map((b) => b.value);
    const payload = { campaign: $("campaign").value, rig: $("rig").value };
    if (chosen.length !== boxes.length) payload.runs = chosen;
    const reply = await act("start " + payload.campaign + " on " + payload.rig, "POST", "/api/start", payload);
    if (reply) {
      if (reply.warning) {
        showMessage("start " + payload.campaign + " on " + payload.rig + ": accepted; warning: " + reply.warning, false);
        events.add("warning", reply.warning, "trip");
      }
      live.setView("follow", null);
    }
  });
  $("stop").addEventListener("click", () => act("stop", "POST", "/api/stop", {}));
  // ABORT, by the button or the Escape key (Escape first closes an open confirm step).
  $("abort").addEventListener("click", () => linkState.abort("from the operator console"));
  document.addEventListener("keydown", (e) => {
    if (e.key !== "Escape" || e.repeat) return;
    if (!$("confirm").hidden) {
      $("confirm-no").click();
      return;
    }
    if (!$("abort").disabled) linkState.abort("from the operator console (Escape key)");
  });

  // Each injection asks first, in the page (window.confirm would block the page and its tests).
  let pending = null;
  function ask(text, action) {
    pending = action;
    $("confirm-text").textContent = text;
    $("confirm").hidden = false;
    $("confirm-yes").focus();
  }
  $("confirm-no").addEventListener("click", () => {
    pending = null;
    $("confirm").hidden = true;
  });
  $("confirm-yes").addEventListener("click", async () => {
    const action = pending;
    pending = null;
    $("confirm").hidden = true;
    if (action) await action();
  });
  const numberIn = (id) => Number($(id).value);
  async function inject(kind, payload, text) {
    // The file records the injection (events.js lists it once): the page adds no copy of its own.
    if (await act("inject " + kind, "POST", "/api/inject/" + kind, payload)) showMessage("inject " + text + ": accepted", true, false, true);
  }
  $("inject-gap").addEventListener("click", () => {
    const gap = numberIn("gap-deg");
    ask("Set the true gap to " + gap + " deg from now on?", () => inject("gap", { gap_deg: gap }, "gap change to " + gap + " deg"));
  });
  $("inject-programme").addEventListener("click", () =>
    ask("Return the gap to the campaign's programme?", () => inject("gap", { programme: true }, "gap back to the programme")));
  function sensorPayload() {
    const mode = $("sensor-mode").value;
    const payload = { mode, duration_s: numberIn("sensor-duration") };
    if (mode === "bias") payload.bias_kpa = numberIn("sensor-value");
    if (mode === "noise") payload.rms_kpa = numberIn("sensor-value");
    return payload;
  }
  $("sensor-mode").addEventListener("change", () => {
    const mode = $("sensor-mode").value;
    $("sensor-value").disabled = mode !== "bias" && mode !== "noise";
    $("sensor-value-label").textContent = mode === "noise" ? "rms kPa" : "kPa";
  });
  $("sensor-mode").dispatchEvent(new Event("change"));
  $("inject-sensor").addEventListener("click", () => {
    const p = sensorPayload();
    const text = "sensor fault " + p.mode + (p.bias_kpa !== undefined ? " " + p.bias_kpa + " kPa" : "") +
      (p.rms_kpa !== undefined ? " " + p.rms_kpa + " kPa rms" : "") + (p.duration_s > 0 ? " for " + p.duration_s + " s" : " until cleared");
    ask("Inject a " + text + "?", () => inject("sensor", p, text));
  });
  $("inject-drive").addEventListener("click", () => {
    const d = numberIn("drive-duration");
    const text = "drive ignores commands " + (d > 0 ? "for " + d + " s" : "until cleared");
    ask("Make the " + text + "?", () => inject("drive", { mode: "ignore_commands", on: true, duration_s: d }, text));
  });
  $("inject-clear").addEventListener("click", () => ask("Clear every injected fault?", () => inject("clear", {}, "faults cleared")));

  window.hilConsole = { plots: live.plots, rows: live.rows, columns: live.columns, view: live.view, yTickFormatter: live.yTickFormatter };

  loadChoices().catch((e) => showMessage("cannot load campaigns and rigs: " + e.message, false));
  runsList.loadModels().catch((e) => showMessage("cannot load the plant models: " + e.message, false));
  refreshRuns();
  pollStatus();
  connect();
})();
