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

  // The last message, in green (ok) or red; it clears itself after kMessageMs unless sticky (what
  // an abort came to), and a restored link clears it (what the lost link made is stale then).
  const kMessageMs = 10000;
  let messageTimer = null;
  function showMessage(text, ok, sticky) {
    const m = $("message");
    m.textContent = text;
    m.className = ok ? "message ok" : "message";
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
  const events = window.hilEvents({ $, body, apiText, ApiRefusal, onMarks: (list) => {
    marks = list;
    dirty = true;
  } });

  // ---------------------------------------------------------------------------------------------
  // Live telemetry: a bounded buffer of rows, plots redrawn on a timer (not per message).
  const kKeepS = 120;         // seconds of telemetry held
  const kMaxRows = 20000;     // and never more rows than this, whatever the rate
  const kFollowSpanS = 30;    // what "follow" shows
  const kRedrawMs = 80;       // at most 12.5 redraws a second
  const columns = ["t_s", "p_ref_mpa", "p_meas_mpa", "theta_cmd_deg", "theta_motor_deg", "theta_valve_deg", "touch_state",
    "motion_intention", "gap_est_deg", "gap_true_deg", "comp_deg"];
  const C = Object.fromEntries(columns.map((c, i) => [c, i]));
  const rows = [];
  let dirty = false;
  let frames = 0;
  let received = 0;
  let droppedTotal = 0;
  body.dataset.framesRendered = "0";
  body.dataset.points = "0";

  const num = (v) => (typeof v === "number" && isFinite(v) ? v : null);
  function addRow(m) {
    const t = num(m.t_s);
    if (t === null) return;
    if (rows.length > 0 && t < rows[rows.length - 1][C.t_s]) rows.length = 0;  // time went back: a new run
    rows.push(columns.map((c) => num(m[c])));
    let drop = 0;
    while (drop < rows.length && (rows[drop][C.t_s] < t - kKeepS || rows.length - drop > kMaxRows)) ++drop;
    if (drop > 0) rows.splice(0, drop);
    ++received;
    dirty = true;
  }

  const plotDefs = [
    { id: "pressure", title: "Pressure (MPa)", labels: ["pressure reference", "measured pressure"], cols: [C.p_ref_mpa, C.p_meas_mpa],
      colors: ["#7f8c8d", "#1565c0"] },
    { id: "angles", title: "Angles (deg): command, motor, valve; compensation jumps marked", labels: ["command", "motor", "valve",
      "compensation jump"], cols: [C.theta_cmd_deg, C.theta_motor_deg, C.theta_valve_deg, -1],
      colors: ["#1565c0", "#2e7d32", "#8e24aa", "#c62828"],
      series: { "compensation jump": { strokeWidth: 0, drawPoints: true, pointSize: 4 } } },
    { id: "observer", title: "Observer: touch state Tf and motion intention Mf", labels: ["touch state", "motion intention"],
      cols: [C.touch_state, C.motion_intention], colors: ["#ef6c00", "#00838f"], stepPlot: true, valueRange: [-1.4, 1.4] },
    { id: "gap", title: "Gap (deg): estimate vs true", labels: ["gap estimate", "true gap"], cols: [C.gap_est_deg, C.gap_true_deg],
      colors: ["#1565c0", "#c62828"] },
  ];
  const plots = {};
  const view = { mode: "follow", range: null };  // follow | fixed (the operator's zoom) | paused
  let syncing = false;  // our own updates: not the operator zooming or panning
  let shownRange = null;  // the x range we last gave the plots
  let marks = [];   // the current run's marked events ({t_s, kind}), drawn as labelled lines

  // Y tick labels with the decimals their spacing needs (dygraphs' default rounds to 2 significant
  // digits, so sub-degree ticks of the gap plot printed as "1" and "1"). Dygraphs spaces ticks by
  // the smallest of 1, 2, 5 x 10^k that leaves pixelsPerLabel pixels between labels; that step,
  // from the axis range and the plot's height, sets the decimals, and a value the step does not
  // predict (another tick rule) gets the decimals it needs itself.
  function yTickFormatter(value, granularity, opts, g) {
    const range = g && g.yAxisRange ? g.yAxisRange() : null;
    const area = g && g.getArea ? g.getArea() : null;
    const h = area && area.h > 0 ? area.h : g && g.graphDiv ? g.graphDiv.clientHeight - 40 : 0;
    const least = range && h > 0 ? (Math.abs(range[1] - range[0]) * (opts("pixelsPerLabel") || 30)) / h : 0;
    let decimals = 0;
    if (least > 0 && isFinite(least)) {
      const k = Math.floor(Math.log10(least));
      const mantissa = [1, 2, 5, 10].find((m) => m * 10 ** k >= least * (1 - 1e-9));
      decimals = Math.max(0, -Math.floor(Math.log10(mantissa * 10 ** k) + 1e-9));
    }
    while (decimals < 6 && Math.abs(value * 10 ** decimals - Math.round(value * 10 ** decimals)) > 1e-6 * Math.max(1, Math.abs(value * 10 ** decimals)))
      ++decimals;
    return value.toFixed(decimals);
  }

  function plotData(def) {
    return rows.map((r) => {
      const out = [r[C.t_s]];
      for (const c of def.cols) out.push(c >= 0 ? r[c] : (r[C.comp_deg] ? r[C.theta_cmd_deg] : null));
      return out;
    });
  }

  function setView(mode, range) {
    view.mode = mode;
    view.range = range;
    $("view-mode").textContent = mode === "follow" ? "following" : mode === "paused" ? "paused (zoom and pan freely)" : "zoomed; streaming";
    $("pause").textContent = mode === "paused" ? "Resume" : "Pause";
    dirty = true;
  }

  // A zoom or a pan in one plot moves them all; the plots keep streaming in that range.
  function onDraw(g, initial) {
    if (syncing || initial) return;
    const range = g.xAxisRange();
    // A redraw in the range we gave (a resize) is not the operator's doing.
    if (shownRange && Math.abs(range[0] - shownRange[0]) < 1e-9 && Math.abs(range[1] - shownRange[1]) < 1e-9) return;
    shownRange = range;
    setView(view.mode === "paused" ? "paused" : "fixed", range);
    syncing = true;
    for (const other of Object.values(plots)) if (other !== g) other.updateOptions({ dateWindow: range });
    syncing = false;
  }

  function underlay(ctx, area, g) {
    ctx.save();
    ctx.strokeStyle = "rgba(198, 40, 40, 0.55)";
    ctx.fillStyle = "rgba(198, 40, 40, 0.9)";
    ctx.font = "10px system-ui, sans-serif";
    ctx.setLineDash([4, 3]);
    let lastLabelX = -Infinity;
    for (const m of marks) {
      const x = g.toDomXCoord(m.t_s);
      if (x < area.x || x > area.x + area.w) continue;
      ctx.beginPath();
      ctx.moveTo(x, area.y);
      ctx.lineTo(x, area.y + area.h);
      ctx.stroke();
      if (x - lastLabelX > 60) {  // labels that would overlap are left to the events list
        ctx.fillText(m.kind.replaceAll("_", " "), x + 2, area.y + 10);
        lastLabelX = x;
      }
    }
    ctx.restore();
  }

  function ensurePlots() {
    if (Object.keys(plots).length > 0) return;
    $("plots-empty").hidden = true;
    // Shown before they are made: a Dygraph takes its div's size then (and follows the window's).
    $("plots").classList.add("live");
    for (const def of plotDefs) {
      const div = $("plot-" + def.id);
      const legend = document.createElement("div");
      legend.className = "legend";
      div.after(legend);
      plots[def.id] = new Dygraph(div, plotData(def), {
        labels: ["t (s)", ...def.labels],
        title: def.title,
        titleHeight: 22,
        colors: def.colors,
        series: def.series || {},
        stepPlot: !!def.stepPlot,
        valueRange: def.valueRange || null,
        legend: "always",
        labelsDiv: legend,
        labelsSeparateLines: false,
        connectSeparatedPoints: false,
        animatedZooms: false,
        xLabelHeight: 0,
        axes: { y: { axisLabelFormatter: yTickFormatter } },
        drawCallback: onDraw,
        underlayCallback: underlay,
      });
      div.addEventListener("dblclick", () => setView("follow", null));
    }
  }

  function redraw() {
    dirty = false;
    if (rows.length < 2 || rows[rows.length - 1][C.t_s] <= rows[0][C.t_s]) return;
    ensurePlots();
    const tLast = rows[rows.length - 1][C.t_s];
    const range = view.mode === "follow" ? [Math.max(rows[0][C.t_s], tLast - kFollowSpanS), tLast] : view.range;
    syncing = true;
    try {
      for (const def of plotDefs) plots[def.id].updateOptions({ file: plotData(def), dateWindow: range });
      shownRange = plots[plotDefs[0].id].xAxisRange();
    } finally {
      syncing = false;
    }
    body.dataset.framesRendered = String(++frames);
    body.dataset.points = String(rows.length);
  }
  setInterval(() => {
    if (dirty && view.mode !== "paused") redraw();
  }, kRedrawMs);

  $("follow").addEventListener("click", () => setView("follow", null));
  $("pause").addEventListener("click", () => {
    if (view.mode === "paused") return setView("follow", null);
    setView("paused", Object.values(plots)[0] ? Object.values(plots)[0].xAxisRange() : null);
  });

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
      if (m.type === "row") return addRow(m);
      if (m.type === "status") {
        linkState.status(m);
        if (m.run_dir && m.state !== "idle") events.setCurrent(m.run_dir);
      } else if (m.type === "run_start") {
        rows.length = 0;
        events.setCurrent(m.dir);
      } else if (m.type === "run_end") {
        linkState.runEnd(m);
        events.add("run_end", m.run + ": " + m.outcome + (m.reason ? " (" + m.reason + ")" : ""), m.outcome === "completed" ? "" : "trip");
        events.follow(m.dir);
        refreshRuns();
      } else if (m.type === "campaign_end") {
        events.add("campaign_end", m.campaign + ": " + m.outcome + (m.reason ? " (" + m.reason + ")" : ""), "");
        refreshRuns();
      } else if (m.type === "dropped") {
        droppedTotal = m.total;
        events.add("dropped", m.messages + " telemetry messages dropped (" + m.why + ")", "");
      }
    };
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
      const last = m.last;
      $("what").textContent = last && last.campaign ? "last: " + last.campaign + ": " + last.outcome + (last.reason ? " (" + last.reason + ")" : "") : "";
      $("progress").value = 0;
      shownCampaign = "";
      return;
    }
    $("what").textContent = (m.campaign || "?") + " · " + (m.run || "?") + " (" + ((m.run_index ?? 0) + 1) + "/" + (m.runs_total ?? "?") + ") on " +
      (m.rig || "?") + " · t " + fmt(m.run_t_s, 1) + "/" + fmt(m.duration_s, 0) + " s";
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

    const dl = $("health-list");
    const items = [];
    const loop = s.loop;
    const tel = s.telemetry || {};
    if (loop) {
      items.push(["scheduling", loop.sched + (loop.memory_locked ? ", memory locked" : ", memory not locked"), false]);
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
    items.push(["live view: rows received / held", received + " / " + rows.length, false]);
    items.push(["live view: messages dropped", droppedTotal, droppedTotal > 0]);
    dl.replaceChildren(...items.flatMap(([k, v, bad]) => {
      const dt = document.createElement("dt");
      dt.textContent = k;
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
      events.setCurrent(s.run_dir);
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
      setView("follow", null);
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
    if (await act("inject " + kind, "POST", "/api/inject/" + kind, payload)) showMessage("inject " + text + ": accepted", true);
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

  // ---------------------------------------------------------------------------------------------
  // Recorded runs, each with its report, its files and its analyses against a plant model.
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

  async function loadRuns() {
    const reply = await api("GET", "/api/runs");
    const tbody = $("runs-table").querySelector("tbody");
    const shown = reply.runs.slice(0, 200);
    tbody.replaceChildren(...shown.map((r) => {
      const tr = document.createElement("tr");
      tr.dataset.run = r.id;
      const cells = [r.id, (r.campaign || "?") + " / " + (r.run || "?"), r.outcome || r.error || "?", r.reason || ""].map((text) => {
        const td = document.createElement("td");
        td.textContent = text;
        return td;
      });
      cells[2].className = "outcome outcome-" + (r.outcome || "error");
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

  window.hilConsole = { plots, rows, columns, view, yTickFormatter };

  loadChoices().catch((e) => showMessage("cannot load campaigns and rigs: " + e.message, false));
  loadModels().catch((e) => showMessage("cannot load the plant models: " + e.message, false));
  refreshRuns();
  pollStatus();
  connect();
})();
