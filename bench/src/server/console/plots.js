// The operator console's live plots (inlined before console.js): a bounded buffer of the
// telemetry WebSocket's rows, four linked Dygraph plots redrawn on a timer, follow / zoom / pause,
// and the run's events marked on them. For tests: body data-frames-rendered (redraws),
// data-points (rows held); each plot's div data-markers (labels drawn), data-windows (shaded).
"use strict";
window.hilPlots = function hilPlots({ $, body, palette }) {
  // A bounded buffer of rows, plots redrawn on a timer (not per message).
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

  // Each signal in the one palette's colour (common/palette/signals.txt), as in every report;
  // every axis with its quantity and unit. A plot's title is a heading above it (it wraps on a
  // phone instead of being cut) with what it shows in words on hover.
  const P = palette;
  const plotDefs = [
    { id: "pressure", title: "Pressure vs reference", tip: "the measured line pressure against the campaign's reference", yLabel: "pressure [MPa]", labels: ["pressure reference", "measured pressure"],
      cols: [C.p_ref_mpa, C.p_meas_mpa], colors: [P.p_ref_mpa, P.p_meas_mpa] },
    { id: "angles", title: "Angles: command, motor, valve; compensation jumps",
      tip: "the angle commanded to the drive, the motor's and the valve's (where the rig knows it); a dot where the backlash compensation jumps the command",
      yLabel: "angle [deg]",
      labels: ["command", "motor", "valve", "compensation jump"], cols: [C.theta_cmd_deg, C.theta_motor_deg, C.theta_valve_deg, -1],
      colors: [P.theta_cmd_deg, P.theta_motor_deg, P.theta_valve_deg, P.comp_deg],
      series: { command: { strokePattern: [6, 4] }, "compensation jump": { strokeWidth: 0, drawPoints: true, pointSize: 4 } } },
    { id: "observer", title: "Which gear flank drives the valve, and where the command goes",
      tip: "touch state (Tf): +1 the positive flank of the gear drives the valve, −1 the negative one, 0 none (the motor crosses the backlash gap); " +
        "motion intention (Mf): +1 the command rises, −1 it falls, 0 it holds",
      yLabel: "state [-1, 0, +1]",
      labels: ["touch state", "motion intention"], cols: [C.touch_state, C.motion_intention], colors: [P.touch_state, P.motion_intention],
      stepPlot: true, valueRange: [-1.4, 1.4] },
    { id: "gap", title: "Backlash gap: estimate vs true", tip: "the observer's estimate of the gear's backlash gap against the true one (known on a simulated valve)",
      yLabel: "gap [deg]", labels: ["gap estimate", "true gap"],
      cols: [C.gap_est_deg, C.gap_true_deg], colors: [P.gap_est_deg, P.gap_true_deg], series: { "true gap": { strokePattern: [6, 4] } } },
  ];
  const plots = {};
  const view = { mode: "follow", range: null };  // follow | fixed (the operator's zoom) | paused
  let syncing = false;  // our own updates: not the operator zooming or panning
  let shownRange = null;  // the x range we last gave the plots
  let marks = [];    // the current run's marked events ({t_s, kind, mark, ...}), drawn as labelled lines
  let windows = [];  // its fault windows ({t0, t1 (NaN: still open), label}), shaded

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

  // The run's events as labelled dashed lines (the label the server gives, worded as the reports:
  // "gap 2.5 deg", "sensor stuck 1.52 MPa") and its fault windows shaded. A label that would
  // overlap the one before goes a row lower (three rows), else it is left to the events list.
  // For tests: each plot's div gets data-markers, the labels drawn in its last frame.
  function underlay(ctx, area, g) {
    ctx.save();
    const tEnd = rows.length ? rows[rows.length - 1][C.t_s] : 0;
    ctx.fillStyle = palette.fault_window;
    let shaded = 0;
    for (const w of windows) {
      const a = Math.max(area.x, g.toDomXCoord(w.t0)), b = Math.min(area.x + area.w, g.toDomXCoord(Number.isFinite(w.t1) ? w.t1 : tEnd));
      if (b > a) ctx.fillRect(a, area.y, b - a, area.h), ++shaded;
    }
    ctx.strokeStyle = ctx.fillStyle = palette.event;
    ctx.font = "10px system-ui, sans-serif";
    ctx.textBaseline = "top";
    ctx.setLineDash([4, 3]);
    const drawn = [], rowEnd = [-Infinity, -Infinity, -Infinity];
    for (const m of marks) {
      const x = Math.round(g.toDomXCoord(m.t_s)) + 0.5;
      if (!(x >= area.x && x <= area.x + area.w)) continue;
      ctx.beginPath();
      ctx.moveTo(x, area.y);
      ctx.lineTo(x, area.y + area.h);
      ctx.stroke();
      const row = rowEnd.findIndex((end) => end < x);
      if (row < 0) continue;
      // Right of its line, or left of it where it would run past the plot's right edge.
      const w = ctx.measureText(m.mark).width;
      ctx.fillText(m.mark, x + 2 + w > area.x + area.w ? x - 2 - w : x + 2, area.y + 2 + 11 * row);
      rowEnd[row] = x + 6 + w;
      drawn.push(m.mark);
    }
    ctx.restore();
    g.graphDiv.parentElement.dataset.markers = JSON.stringify(drawn);
    g.graphDiv.parentElement.dataset.windows = String(shaded);
  }

  // Marks from the run's events (those the feed labelled), and the windows of its faults: a
  // duration ends one, else it lasts until it expires, is cleared or replaced (open: to the newest row).
  function setMarks(list) {
    marks = list.filter((e) => typeof e.t_s === "number" && typeof e.mark === "string");
    windows = [];
    const open = {};
    const close = (which, t) => {
      if (open[which] && !Number.isFinite(open[which].t1)) open[which].t1 = t;
      open[which] = null;
    };
    for (const e of marks) {
      const drive = e.kind === "drive_fault" || (e.kind === "fault_expired" && e.fault === "drive");
      const which = drive ? "drive" : "sensor";
      if (e.kind === "faults_cleared") close("drive", e.t_s), close("sensor", e.t_s);
      else if (e.kind === "fault_expired" || e.kind === "sensor_fault" || e.kind === "drive_fault") close(which, e.t_s);
      if ((e.kind === "sensor_fault" || e.kind === "drive_fault") && e.mode !== "none" && e.on !== false) {
        const w = { t0: e.t_s, t1: e.duration_s > 0 ? e.t_s + e.duration_s : NaN, label: e.mark };
        windows.push(w);
        open[which] = w;
      }
    }
    dirty = true;
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
      const heading = document.createElement("h3");
      heading.className = "plot-title";
      heading.textContent = def.title;
      heading.title = def.tip;
      div.before(heading);
      plots[def.id] = new Dygraph(div, plotData(def), {
        labels: ["t [s]", ...def.labels],
        xlabel: "run time t [s]",
        ylabel: def.yLabel,
        colors: def.colors,
        series: def.series || {},
        stepPlot: !!def.stepPlot,
        valueRange: def.valueRange || null,
        legend: "always",
        labelsDiv: legend,
        labelsSeparateLines: false,
        connectSeparatedPoints: false,
        animatedZooms: false,
        xLabelHeight: 14,
        yLabelWidth: 14,
        axisLabelFontSize: 11,
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

  return {
    addRow,
    setMarks,
    setView,
    clear: () => {
      rows.length = 0;
      dirty = true;
    },
    counts: () => ({ received, held: rows.length }),
    plots, rows, columns, view, yTickFormatter,
  };
};
