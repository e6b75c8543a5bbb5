// hilbench report: turns each figure's JSON (in a non-executed script element of class hil-data,
// written by report.cpp) into a Dygraph (Debian's libjs-dygraphs, inlined before this script).
// Dygraphs draws, and does the axes, box zoom, shift+drag pan, double-click reset and the hover
// read-out; this layer adds what a report needs on top: series styles, bands and reference lines,
// linked x zoom and cursor within a group, wheel zoom, a legend that hides series, grouped bars (a
// dygraphs plotter) and sortable tables.
// For tests: each plot's canvas gets class hil-plot, data-rendered="1", data-ink (pixels the data
// drew on the first draw; only when the page is opened with #ink, as the tests do: reading the
// pixels back was 70 % of an hour's report's opening) and data-empty="1" without data; <body> gets data-plots,
// data-plot-errors and data-plot-error-first; the underlay's canvas data-markers (event labels drawn); window.hilReport.charts lists the charts.
// A thinned plot says so under its legend (.hil-res, class hil-thin); zoomed in on a served report it
// fetches every sample of the window (class hil-full, data-rows: the rows in the table).
(function () {
  'use strict';

  const PALETTE = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22', '#17becf'];
  const stats = { plots: 0, errors: 0, first: '' };
  const charts = [];
  const groups = new Map();  // group name -> charts sharing x zoom and the hover cursor
  const COMMON = { connectSeparatedPoints: true, animatedZooms: false, legend: 'follow', gridLineColor: '#e8ebf0',
    axisLineColor: '#c3cad6', axisLabelFontSize: 12, xLabelHeight: 16, yLabelWidth: 16, highlightCircleSize: 3.5,
    resizable: 'passive' };

  const esc = s => String(s).replace(/[&<>"']/g, c => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
  // Read-out value: 6 significant digits, no trailing zeros.
  function fmtVal(v) {
    if (v === null || v === undefined || !isFinite(v)) return '\u2014';
    const a = Math.abs(v);
    return a !== 0 && (a >= 1e7 || a < 1e-4) ? v.toExponential(4).replace('e+', 'e') : String(Number(v.toPrecision(6)));
  }
  // Log-axis tick label: 3 significant digits, exponent form outside 0.001 to 1e5 ("4e-4").
  function fmtLogTick(v) {
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2).replace(/\.?0+e/, 'e').replace('e+', 'e');
    return String(Number(v.toPrecision(3)));
  }
  const swatch = it => '<span class="hil-sw ' + it.kind + '" style="' +
    (it.kind === 'dashed' || it.kind === '' ? 'border-top-color:' : 'background:') + esc(it.color) + '"></span>';

  // Dygraph wants one table: a row per x, a column per series. Series that share their x (report.cpp
  // decimates a figure's lines over the same buckets and writes "xOf" for the x of another) give
  // a row per x directly. Otherwise entries of all series sorted by x fill rows; a series without a
  // value at a row's x gets null, which connectSeparatedPoints skips. A gap in a series (NaN or
  // null in the JSON) is NaN, which dygraphs draws as a break. On a log axis, values <= 0 are left out.
  function toRows(series, xLog, yLog) {
    const yOf = v => (v === null || !isFinite(v) ? NaN : v);
    const shared = series.length > 0 && series.every(s => s.x === series[0].x && s.y.length === s.x.length);
    // A value inside a run of equal values of its series is null: the drawn line is the same
    // (connected over), and dygraphs draws only the run's ends (a step that is flat while the
    // measurement beside it moves costs no segments).
    if (shared) {
      const xs = series[0].x, rows = [];
      let sorted = true;
      for (let k = 0; k < xs.length && sorted; k++) {
        const x = xs[k];
        if (x === null || !isFinite(x) || (xLog && x <= 0)) continue;
        if (rows.length && x < rows[rows.length - 1][0]) sorted = false;
        const row = [x];
        for (const s of series) {
          const y = yOf(s.y[k]);
          row.push((yLog && y <= 0) || (k > 0 && k + 1 < xs.length && s.y[k - 1] === y && s.y[k + 1] === y) ? null : y);
        }
        rows.push(row);
      }
      if (sorted) return rows;
    }
    const entries = [];
    series.forEach((s, j) => {
      for (let k = 0; k < Math.min(s.x.length, s.y.length); k++) {
        const x = s.x[k], y = yOf(s.y[k]);
        if (x !== null && isFinite(x) && !(xLog && x <= 0) && !(yLog && y <= 0)) entries.push([x, j, y, k]);
      }
    });
    entries.sort((a, b) => a[0] - b[0] || a[1] - b[1] || a[3] - b[3]);
    const rows = [];
    let row = null;
    for (const [x, j, y] of entries) {
      if (!row || row[0] !== x || row[j + 1] !== null) rows.push((row = [x, ...series.map(() => null)]));
      row[j + 1] = y;
    }
    return rows;
  }

  // Counts the pixels of the plot area that the data drew: the canvas read back before the series
  // are drawn (a plotter ahead of the real one: dygraphs runs plugins' willDrawChart in reverse
  // order, so a plugin would read before the grid and axes) against after. Only on a chart's
  // first draw: reading pixels back costs more than drawing.
  function inkCounter(chart) {
    let before = null, box = null;
    const pixels = e => new Uint32Array(e.drawingContext.getImageData(...box).data.buffer);
    const snapshot = e => {
      if (e.seriesIndex !== 0 || !chart.countInk) return;
      const a = e.dygraph.getArea(), c = e.drawingContext.canvas, r = c.width / (parseFloat(c.style.width) || c.width);
      box = [a.x, a.y, a.w, a.h].map(v => Math.max(1, Math.floor(v * r)));
      before = pixels(e);
    };
    const plugin = { toString: () => 'hil ink counter', activate: () => ({
      willDrawChart: e => {
        e.canvas.classList.add('hil-plot');
        if (chart.empty) e.canvas.setAttribute('data-empty', '1');
      },
      didDrawChart: e => {
        e.canvas.setAttribute('data-rendered', '1');
        if (!chart.countInk || !before) return;
        const after = pixels(e);
        let ink = 0;
        for (let i = 0; i < after.length; i++) if (after[i] !== before[i]) ink++;
        e.canvas.setAttribute('data-ink', String(ink));
        chart.countInk = false;
        before = null;
      },
    }) };
    return { plugin, plotters: draw => [snapshot, draw] };
  }

  // Steps as one path: dygraphs' own step drawing starts a sub-path at every point (moveTo, then
  // across and up), which the rasteriser strokes one by one and a dash pattern restarts on; a
  // figure of long steps opened measurably slower. Lines go to dygraphs' plotter. A point without a
  // value (null) is connected over; NaN is a gap, up to which the step holds; a point alone
  // between gaps is drawn as a dot.
  function linesAndSteps(e) {
    const g = e.dygraph;
    if (!g.getBooleanOption('stepPlot', e.setName)) return Dygraph.Plotters.linePlotter(e);
    const ctx = e.drawingContext, pattern = g.getOption('strokePattern', e.setName), single = [];
    if (pattern) ctx.setLineDash(pattern);
    ctx.beginPath();
    let px = null, py = null, run = 0;
    for (const p of e.points) {
      if (p.yval === null) continue;
      if (!(p.canvasy === p.canvasy)) {  // NaN: a gap
        if (px !== null) ctx.lineTo(p.canvasx, py);
        if (run === 1) single.push([px, py]);
        px = null, run = 0;
        continue;
      }
      if (px === null) ctx.moveTo(p.canvasx, p.canvasy);
      else ctx.lineTo(p.canvasx, py), ctx.lineTo(p.canvasx, p.canvasy);
      px = p.canvasx, py = p.canvasy, run++;
    }
    if (run === 1) single.push([px, py]);
    ctx.stroke();
    if (pattern) ctx.setLineDash([]);
    ctx.fillStyle = e.color;
    for (const [x, y] of single) ctx.fillRect(x - 1.5, y - 1.5, 3, 3);
  }

  // Wheel zoom around the cursor in x: ctrl/cmd+wheel always, plain wheel once the plot has been
  // clicked (so scrolling the page past plots does not zoom them).
  const wheelModel = chart => Object.assign({}, Dygraph.defaultInteractionModel, {
    mousedown: (e, g, ctx) => {
      for (const c of charts) c.fig.classList.toggle('hil-active', (c.active = c === chart));
      Dygraph.defaultInteractionModel.mousedown(e, g, ctx);
    },
    wheel: (e, g) => {
      if (!(chart.active || e.ctrlKey || e.metaKey)) return;
      e.preventDefault();
      const dy = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaMode === 2 ? e.deltaY * 400 : e.deltaY;
      const f = Math.exp(Math.max(-400, Math.min(400, dy)) * 0.0015), log = chart.spec.xLog;
      const [x0, x1] = g.xAxisRange().map(v => (log ? Math.log10(v) : v)), area = g.getArea();
      const c = x0 + Math.max(0, Math.min(1, (e.clientX - g.graphDiv.getBoundingClientRect().left - area.x) / area.w)) * (x1 - x0);
      g.updateOptions({ dateWindow: [c - (c - x0) * f, c + (x1 - c) * f].map(v => (log ? Math.pow(10, v) : v)) });
    },
  });

  // Legend buttons: click hides or shows a series, double-click shows it alone (again: all).
  function legend(chart, items) {
    const bar = chart.fig.querySelector('.hil-legend');
    const toggles = items.filter(s => s.toggles), apply = () => toggles.forEach(o => {
      o.button.classList.toggle('off', o.hidden);
      chart.graph.setVisibility(o.index, !o.hidden);
    });
    for (const s of items) {
      const b = document.createElement(s.toggles ? 'button' : 'span');
      b.className = 'hil-lg' + (s.toggles ? '' : ' static');
      b.innerHTML = swatch(s) + esc(s.name);
      bar.append(b);
      if (!s.toggles) continue;
      Object.assign(s.button = b, { type: 'button', title: 'click: hide/show, double-click: show only this' + (s.note || '') });
      b.addEventListener('click', () => { s.hidden = !s.hidden; apply(); });
      b.addEventListener('dblclick', () => {
        const alone = toggles.every(o => o === s || o.hidden);
        toggles.forEach(o => { o.hidden = alone ? false : o !== s; });
        apply();
      });
    }
  }

  // Every sample on zoom. A figure's lines are a thinned overview (min and max per bucket, spikes
  // kept) of series that name their source (src: a run and a telemetry column). Opened through
  // hilbench serve, a zoomed plot asks GET /api/runs/RUN/telemetry for its window at full
  // resolution once the window holds few enough rows (the server's bound), and draws those rows
  // alone; zoomed out again it draws the overview. A line under the legend says which it shows.
  const DETAIL_MAX_ROWS = 20000, DETAIL_PAD = 0.05;
  const served = /^https?:$/.test(location.protocol);
  const token = new URLSearchParams(location.search).get('token');
  const detailCols = new Map();    // run -> the columns any plot wants from it (one fetch serves a group)
  const detailFetches = new Map();  // "run from to" -> the fetch's promise
  const fmtMs = ms => (ms >= 1000 ? fmtVal(Number((ms / 1000).toPrecision(3))) + ' s' : fmtVal(Number(ms.toPrecision(3))) + ' ms');
  function setRes(chart, cls, text) {
    chart.res.className = 'hil-res ' + cls;
    chart.res.textContent = text;
  }
  function detailSetup(chart, series) {
    const xs = chart.rows.map(r => r[0]), thin = series.filter(s => s.n > s.x.length && s.style !== 'points');
    chart.res = document.createElement('div');
    chart.fig.querySelector('.hil-legend').after(chart.res);
    if (!thin.length || xs.length < 2) return setRes(chart, 'hil-none', '');
    chart.overview = chart.rows;
    chart.span = [xs[0], xs[xs.length - 1]];
    chart.samples = Math.max(...thin.map(s => s.n));
    chart.src = series.map(s => s.src || null);
    for (const src of chart.src) if (src) detailCols.set(src.run, (detailCols.get(src.run) || new Set()).add(src.col));
    const every = ((chart.span[1] - chart.span[0]) * 1000 * 2) / Math.max(...thin.map(s => s.x.length));
    const runs = [...new Set(chart.src.filter(Boolean).map(s => s.run))];
    chart.thinText = 'thinned: min and max per ' + fmtMs(every) + ' (' + chart.samples.toLocaleString('en') + ' samples drawn as ' +
      Math.max(...thin.map(s => s.x.length)).toLocaleString('en') + ' points)';
    chart.howText = !runs.length ? 'every sample is in the data the report was made from'
      : served ? 'zoom in for every sample'
      : 'every sample on zoom needs the server: hilbench serve --runs-dir <the runs folder>, then /api/runs/' + runs[0] + '/report.html';
    setRes(chart, 'hil-thin', chart.thinText + '; ' + chart.howText);
  }
  function fetchRange(run, from, to) {
    const key = run + ' ' + from + ' ' + to;
    if (!detailFetches.has(key)) {
      const q = new URLSearchParams({ from_s: String(from), to_s: String(to), columns: [...detailCols.get(run)].join(',') });
      if (token) q.set('token', token);
      detailFetches.set(key, fetch('/api/runs/' + encodeURIComponent(run) + '/telemetry?' + q).then(async r => {
        const j = await r.json().catch(() => ({}));
        if (!r.ok) throw new Error(j.detail || j.error || 'HTTP ' + r.status);
        return j;
      }));
      if (detailFetches.size > 16) detailFetches.delete(detailFetches.keys().next().value);
    }
    return detailFetches.get(key);
  }
  function showRows(chart, rows, detail) {
    chart.rows = rows;
    chart.detail = detail;
    chart.graph.updateOptions({ file: rows, dateWindow: chart.graph.isZoomed('x') ? chart.graph.xAxisRange() : null });
  }
  async function loadDetail(chart) {
    const g = chart.graph, [a, b] = g.xAxisRange();
    if (!g.isZoomed('x')) {
      if (chart.detail) showRows(chart, chart.overview, null);
      return setRes(chart, 'hil-thin', chart.thinText + '; ' + chart.howText);
    }
    if (chart.detail && chart.detail.from <= a && chart.detail.to >= b) return;
    const rows = (chart.samples * (b - a)) / (chart.span[1] - chart.span[0]);
    const runs = [...new Set(chart.src.filter(Boolean).map(s => s.run))];
    if (!served || !runs.length || rows * (1 + 2 * DETAIL_PAD) > DETAIL_MAX_ROWS) {
      if (chart.detail) showRows(chart, chart.overview, null);
      const why = !served || !runs.length ? chart.howText : 'zoom to under ' + fmtMs((DETAIL_MAX_ROWS * 900 * (chart.span[1] - chart.span[0])) /
        chart.samples / (1 + 2 * DETAIL_PAD)) + ' for every sample';
      return setRes(chart, 'hil-thin', chart.thinText + '; ' + why);
    }
    const pad = (b - a) * DETAIL_PAD, from = Number((a - pad).toPrecision(9)), to = Number((b + pad).toPrecision(9));
    setRes(chart, 'hil-thin hil-loading', chart.thinText + '; fetching every sample of the window\u2026');
    try {
      const got = await Promise.all(runs.map(run => fetchRange(run, from, to)));
      const [a2, b2] = g.xAxisRange();
      if (a2 < from || b2 > to) return;  // zoomed elsewhere meanwhile: that zoom's own fetch draws
      // One pseudo-series per plotted series on its run's rows; toRows merges runs of other times.
      const parts = chart.spec.series.map((s, i) => {
        const src = chart.src[i], j = src ? got[runs.indexOf(src.run)] : null;
        const col = j && j.columns[src.col];
        return col ? { x: j.t_s, y: col, style: s.style } : { x: [], y: [], style: s.style };
      });
      const table = toRows(parts, chart.spec.xLog, chart.spec.yLog);
      const shown = table.filter(r => r[0] >= a2 && r[0] <= b2).length;
      showRows(chart, table.length ? table : chart.overview, table.length ? { from, to, rows: table.length } : null);
      chart.res.setAttribute('data-rows', String(table.length));
      setRes(chart, 'hil-full', 'every sample: ' + shown.toLocaleString('en') + ' rows in view, read from telemetry.csv');
    } catch (e) {
      setRes(chart, 'hil-thin hil-error', chart.thinText + '; every sample could not be fetched: ' + ((e && e.message) || e));
    }
  }
  function wantDetail(chart) {
    if (!chart.overview) return;
    clearTimeout(chart.detailTimer);
    chart.detailTimer = setTimeout(() => loadDetail(chart), 120);
  }

  // The ink count reads every plot's pixels back twice (getImageData): 1.46 s of the 2.1 s of script
  // that opened a one-hour report. A test asks for it in the fragment, which never reaches a server.
  const COUNT_INK = location.hash.split(/[#&]/).includes('ink');

  function makeChart(fig, spec, items, labels) {
    fig.insertAdjacentHTML('beforeend', '<div class="hil-legend"></div><div class="hil-canvas"><div class="hil-graph" style="height:' +
      (spec.height || 260) + 'px"></div><button type="button" class="hil-reset" title="or double-click the plot">reset zoom</button></div>');
    const chart = { fig, spec, kind: spec.kind, group: spec.group || '', countInk: COUNT_INK, active: false, items, labels,
      div: fig.querySelector('.hil-graph'), resetButton: fig.querySelector('.hil-reset') };
    chart.resetButton.addEventListener('click', () => chart.graph.resetZoom());
    return chart;
  }

  // A series' value at x where its own samples do not fall on that row: lines interpolate, steps
  // hold, so the read-out is the drawn curve; null outside the series or for scatter.
  function valueAt(s, x) {
    let lo = 0, hi = s.x.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (s.x[mid] < x) lo = mid + 1; else hi = mid; }
    if (s.x[lo] === x) return s.y[lo];
    if (s.style === 'points' || lo === 0 || lo >= s.x.length) return null;
    const y0 = s.y[lo - 1], y1 = s.y[lo];
    if (y0 === null || (y1 === null && s.style !== 'step')) return NaN;  // inside a gap
    return s.style === 'step' ? y0 : y0 + ((y1 - y0) * (x - s.x[lo - 1])) / (s.x[lo] - s.x[lo - 1]);
  }

  // Read-out next to the cursor: x with its axis name, every visible series, the band under it.
  const readout = (chart, xName, xText) => data => {
    if (data.x === undefined || data.x === null) return '';
    const rows = data.series.filter(s => s.isVisible).map(s => {
      const i = chart.labels.indexOf(s.label), it = chart.items[i];
      const y = s.y !== undefined && s.y !== null ? s.y : chart.spec.series ? valueAt(chart.spec.series[i], data.x) : null;
      return swatch(it) + esc(it.name) + '<span class="v">' + fmtVal(y) + '</span>';
    });
    for (const b of chart.spec.bands || []) {
      if (b.label && data.x >= Math.min(b.x0, b.x1) && data.x <= Math.max(b.x0, b.x1)) rows.push('<span class="band">\u25A0 ' + esc(b.label) + '</span>');
    }
    return '<div class="hd">' + esc(xName) + ' = ' + esc(xText(data.x)) + '</div>' + (rows.length ? rows.join('<br>') : 'no value here');
  };

  // A zoom, pan or reset in one chart of a group moves the others; the hover cursor follows too.
  let syncing = false;
  const peers = chart => (chart.group ? groups.get(chart.group).filter(o => o !== chart && o.graph) : []);
  const onDraw = chart => (g, initial) => {
    // An empty plot's fixed y range is not a zoom.
    chart.resetButton.style.visibility = g.isZoomed('x') || (!chart.empty && g.isZoomed('y')) ? 'visible' : 'hidden';
    if (!initial) wantDetail(chart);
    if (initial || syncing) return;
    syncing = true;
    try {
      const range = g.isZoomed('x') ? g.xAxisRange() : null;
      for (const o of peers(chart)) {
        const r = o.graph.isZoomed('x') ? o.graph.xAxisRange() : null;
        if (range !== r && !(range && r && range[0] === r[0] && range[1] === r[1])) o.graph.updateOptions({ dateWindow: range });
      }
    } finally {
      syncing = false;
    }
  };
  function hoverLinked(chart, x) {
    for (const o of peers(chart)) {
      if (x === null || !o.rows.length) { o.graph.clearSelection(); continue; }
      let lo = 0, hi = o.rows.length;  // the row nearest x
      while (lo < hi) { const mid = (lo + hi) >> 1; if (o.rows[mid][0] < x) lo = mid + 1; else hi = mid; }
      if (lo > 0 && (lo >= o.rows.length || x - o.rows[lo - 1][0] < o.rows[lo][0] - x)) lo--;
      o.graph.setSelection(lo, undefined, false);
    }
  }

  // Bands (failing windows) and horizontal reference lines, under the data.
  const underlay = spec => (ctx, area, g) => {
    ctx.save();
    ctx.globalAlpha = 0.12;
    for (const b of spec.bands || []) {
      ctx.globalAlpha = b.color && b.color.startsWith('rgba') ? 1 : 0.12;  // a colour with its own alpha keeps it
      const a = Math.max(area.x, g.toDomXCoord(Math.min(b.x0, b.x1))), c = Math.min(area.x + area.w, g.toDomXCoord(Math.max(b.x0, b.x1)));
      ctx.fillStyle = b.color || '#d62728';
      ctx.fillRect(a, area.y, c - a, area.h);
    }
    Object.assign(ctx, { globalAlpha: 1, strokeStyle: '#5b6475', fillStyle: '#5b6475', font: '11px sans-serif' });
    // A line's label sits above it at the left, else below it, else right of the labels it would
    // overlap (lines closer than a label's height, e.g. +-3 sigma on a wide range); the boxes drawn
    // are listed on the canvas (data-hline-labels) for tests.
    const boxes = [], overlaps = b => boxes.some(o => b.x < o.x + o.w && o.x < b.x + b.w && b.y < o.y + o.h && o.y < b.y + b.h);
    for (const h of spec.hlines || []) {
      const y = Math.round(g.toDomYCoord(h.y)) + 0.5;
      if ((spec.yLog && !(h.y > 0)) || !(y >= area.y && y <= area.y + area.h)) continue;
      ctx.setLineDash(h.dashed === false ? [] : [5, 4]);
      ctx.beginPath();
      ctx.moveTo(area.x, y);
      ctx.lineTo(area.x + area.w, y);
      ctx.stroke();
      if (!h.label) continue;
      const w = Math.ceil(ctx.measureText(h.label).width), lh = 12;
      const above = y - 3 - lh >= area.y, below = y + 3 + lh <= area.y + area.h;
      const rows = [above ? y - 3 - lh : null, below ? y + 3 : null, above ? null : y + 3].filter(v => v !== null);
      let box = null;
      for (let x = area.x + 4; !box && x + w <= area.x + area.w; ) {
        box = rows.map(top => ({ x, y: top, w, h: lh })).find(b => !overlaps(b)) || null;
        if (!box) x = Math.max(...boxes.filter(o => o.x + o.w >= x).map(o => o.x + o.w)) + 8;
      }
      if (!box) continue;  // no room left on the plot: the line alone
      ctx.fillText(h.label, box.x, box.y + lh - 2);
      boxes.push(Object.assign(box, { label: h.label }));
    }
    ctx.canvas.setAttribute('data-hline-labels', JSON.stringify(boxes.map(b => [b.label, b.x, b.y, b.w, b.h])));
    // Events as labelled dashed lines; a label that would overlap the one before goes a row lower
    // (three rows), and the labels drawn are listed on the canvas (data-markers) for tests.
    Object.assign(ctx, { font: '10px sans-serif', textBaseline: 'top' });
    const drawn = [], rowEnd = [-Infinity, -Infinity, -Infinity];
    for (const m of spec.markers || []) {
      const x = Math.round(g.toDomXCoord(m.x)) + 0.5;
      if (!(x >= area.x && x <= area.x + area.w)) continue;
      ctx.strokeStyle = ctx.fillStyle = m.color || window.hilPalette.event;
      ctx.setLineDash([4, 3]);
      ctx.beginPath();
      ctx.moveTo(x, area.y);
      ctx.lineTo(x, area.y + area.h);
      ctx.stroke();
      const row = rowEnd.findIndex(end => end < x);
      if (!m.label || row < 0) continue;
      const w = ctx.measureText(m.label).width;  // right of its line, or left where it would leave the plot
      ctx.fillText(m.label, x + 2 + w > area.x + area.w ? x - 2 - w : x + 2, area.y + 2 + 12 * row);
      rowEnd[row] = x + 6 + w;
      drawn.push(m.label);
    }
    ctx.setLineDash([]);
    ctx.canvas.setAttribute('data-markers', JSON.stringify(drawn));
    ctx.restore();
  };

  function plot(fig, spec) {
    const series = spec.series || [];
    series.forEach(s => { if (!s.x && series[s.xOf]) s.x = series[s.xOf].x; s.x = s.x || []; s.y = s.y || []; });
    const chart = makeChart(fig, spec, series.map((s, i) => ({
      index: i, name: s.name || 'series ' + (i + 1), color: s.color || PALETTE[i % PALETTE.length], hidden: false, toggles: true,
      kind: s.style === 'points' ? 'dot' : s.dashed ? 'dashed' : '',
      note: s.n > s.x.length ? ' (' + s.n.toLocaleString('en') + ' points, drawn as ' + s.x.length + ')' : '',
    })), series.map((s, i) => 's' + i));  // names may repeat or hold markup; dygraphs' labels must not
    chart.rows = toRows(series, spec.xLog, spec.yLog);
    chart.empty = !chart.rows.some(r => r.some((v, i) => i > 0 && v !== null && isFinite(v)));
    // Lines 1 px wide: Skia draws a stroke of at most one device pixel as a hairline; at 1.25 px it
    // outlines the stroke as a polygon and fills it, which for a min/max envelope (a zigzag of near
    // vertical segments) cost half the renderer's CPU to open an hour's report (docs/benchmarks.md).
    const opts = {};
    series.forEach((s, i) => {
      opts[chart.labels[i]] = Object.assign({ color: chart.items[i].color, strokeWidth: 1, stepPlot: s.style === 'step' },
        s.style === 'points' ? { drawPoints: true, strokeWidth: 0, pointSize: 1.8 } : {}, s.dashed ? { strokePattern: [6, 4] } : {});
    });
    const items = series.length === 1 && !series[0].name ? [] : chart.items.slice();
    // One legend entry per kind of band (its legend name, else its label): twelve change points are one entry.
    for (const b of spec.bands || []) {
      const name = b.legend || b.label;
      if (name && !items.some(it => it.name === name && !it.toggles)) items.push({ name, color: b.color || '#d62728', kind: 'box band' });
    }
    if (chart.group) groups.set(chart.group, (groups.get(chart.group) || []).concat([chart]));
    const ink = inkCounter(chart), axis = log => Object.assign({ logscale: !!log }, log ? { axisLabelFormatter: fmtLogTick } : {});
    chart.graph = new Dygraph(chart.div, chart.empty ? [0, 1].map(x => [x, ...series.map(() => null)]) : chart.rows, Object.assign({}, COMMON, {
      labels: ['x', ...chart.labels], series: opts, xlabel: esc(spec.xLabel || ''), ylabel: esc(spec.yLabel || ''),
      axes: { x: axis(spec.xLog), y: axis(spec.yLog) }, valueRange: chart.empty ? [0, 1] : null,
      legendFormatter: readout(chart, spec.xLabel || 'x', fmtVal), underlayCallback: underlay(spec), drawCallback: onDraw(chart),
      highlightCallback: (e, x) => hoverLinked(chart, x), unhighlightCallback: () => hoverLinked(chart, null),
      interactionModel: wheelModel(chart), plugins: [ink.plugin], plotter: ink.plotters(linesAndSteps),
    }));
    legend(chart, items);
    detailSetup(chart, series);
    if (chart.empty) chart.div.insertAdjacentHTML('afterend', '<div class="hil-nodata">no data</div>');
    return chart;
  }

  // Grouped bars: category i at x = i, one bar per visible group side by side, values above the
  // bars when they have room. The dygraphs plotter option; every group drawn by the first call.
  const barPlotter = chart => e => {
    if (e.seriesIndex !== 0) return;
    const g = e.dygraph, ctx = e.drawingContext, sets = e.allSeriesPoints, y0 = g.toDomYCoord(0);
    const inner = (g.toDomXCoord(1) - g.toDomXCoord(0)) * 0.78, bw = inner / Math.max(1, sets.length);
    const room = bw >= 30 && chart.cats.length * sets.length <= 48;
    Object.assign(ctx, { font: '11px sans-serif', textAlign: 'center' });
    sets.forEach((points, j) => points.forEach(p => {
      if (p.yval === null || !isFinite(p.yval)) return;
      const x = p.canvasx - inner / 2 + j * bw;
      ctx.fillStyle = chart.items[chart.labels.indexOf(p.name)].color;
      ctx.fillRect(x + 0.5, Math.min(p.canvasy, y0), Math.max(1, bw - 1), Math.max(1, Math.abs(y0 - p.canvasy)));
      if (!room) return;
      Object.assign(ctx, { fillStyle: '#4a5263', textBaseline: p.yval >= 0 ? 'bottom' : 'top' });
      ctx.fillText(fmtVal(Number(p.yval.toPrecision(3))), x + bw / 2, p.canvasy + (p.yval >= 0 ? -2 : 2));
    }));
  };

  function bars(fig, spec) {
    const cats = spec.categories || [], grs = spec.groups || [];
    const chart = makeChart(fig, spec, grs.map((gr, i) => ({ index: i, name: gr.name || 'group ' + (i + 1),
      color: PALETTE[i % PALETTE.length], kind: 'box', hidden: false, toggles: true })), grs.map((gr, i) => 'g' + i));
    chart.cats = cats;
    chart.rows = cats.map((c, i) => [i, ...grs.map(gr => (gr.values[i] === null ? NaN : gr.values[i]))]);
    chart.empty = !chart.rows.some(r => r.some((v, i) => i > 0 && isFinite(v)));
    // Each category's label gets its slot's width and wraps in it.
    const slot = Math.max(30, ((fig.clientWidth || 600) - 70) / Math.max(1, cats.length));
    const ink = inkCounter(chart);
    // A name_with_underscores may break after each underscore; a word longer than its slot anywhere.
    const label = c => '<span title="' + esc(c) + '">' + esc(c.length > 28 ? c.slice(0, 27) + '\u2026' : c).replace(/_/g, '_<wbr>') + '</span>';
    chart.graph = new Dygraph(chart.div, chart.rows.length ? chart.rows : [[0, ...grs.map(() => null)]], Object.assign({}, COMMON, {
      labels: ['category', ...chart.labels], ylabel: esc(spec.yLabel || ''), includeZero: true, valueRange: chart.empty ? [0, 1] : null,
      dateWindow: [-0.5, Math.max(0.5, cats.length - 0.5)], plotter: ink.plotters(barPlotter(chart)), xAxisHeight: 46,
      axes: { x: { drawGrid: false, axisLabelWidth: slot, ticker: () => cats.map((c, i) => ({ v: i, label: label(c) })) } },
      legendFormatter: readout(chart, 'category', i => (cats[Math.round(i)] === undefined ? '' : cats[Math.round(i)])),
      interactionModel: { dblclick: () => {} },  // categories: nothing to zoom or pan
      drawCallback: () => { chart.resetButton.style.visibility = 'hidden'; }, plugins: [ink.plugin],
    }));
    legend(chart, grs.length > 1 || (grs.length === 1 && grs[0].name) ? chart.items : []);
    return chart;
  }

  // Tables: click a header to sort by that column (numerically if every cell is a number).
  function sortable(table) {
    const heads = table.querySelectorAll('thead th');
    heads.forEach((th, col) => th.addEventListener('click', () => {
      const body = table.tBodies[0];
      if (!body) return;
      const rows = Array.from(body.rows), cell = r => (r.cells[col] ? r.cells[col].textContent.trim() : '');
      const numeric = rows.every(r => cell(r) === '' || isFinite(parseFloat(cell(r))));
      const dir = th.getAttribute('data-sort') === 'asc' ? -1 : 1;
      heads.forEach(h => h.removeAttribute('data-sort'));
      th.setAttribute('data-sort', dir > 0 ? 'asc' : 'desc');
      rows.sort((a, b) => dir * (numeric ? (parseFloat(cell(a)) || 0) - (parseFloat(cell(b)) || 0)
        : cell(a).localeCompare(cell(b), undefined, { numeric: true })));
      for (const r of rows) body.append(r);
    }));
  }

  function publish() {
    document.body.setAttribute('data-plots', String(stats.plots));
    document.body.setAttribute('data-plot-errors', String(stats.errors));
    if (stats.first) document.body.setAttribute('data-plot-error-first', stats.first);
  }

  function fail(fig, e) {
    stats.errors++;
    if (!stats.first) stats.first = String((e && e.message) || e);
    if (fig && !fig.querySelector('.hil-failed')) {
      fig.insertAdjacentHTML('beforeend', '<div class="hil-failed"></div>');
      fig.querySelector('.hil-failed').textContent = 'This plot could not be drawn: ' + ((e && e.message) || e);
    }
    publish();
  }

  window.hilReport = { charts, stats };

  function start() {
    for (const fig of document.querySelectorAll('figure.hil-fig')) {
      try {
        const spec = JSON.parse(fig.querySelector('script.hil-data').textContent);
        charts.push(spec.kind === 'bars' ? bars(fig, spec) : plot(fig, spec));
        stats.plots++;
      } catch (e) {
        fail(fig, e);
      }
    }
    document.querySelectorAll('table.hil-table').forEach(sortable);
    document.addEventListener('mousedown', e => {  // a click outside every plot: plain wheel scrolls again
      if (!(e.target.closest && e.target.closest('.hil-canvas'))) for (const c of charts) c.fig.classList.toggle('hil-active', (c.active = false));
    });
    publish();
  }

  window.addEventListener('error', e => { stats.errors++; if (!stats.first) stats.first = String(e.message); publish(); });
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
