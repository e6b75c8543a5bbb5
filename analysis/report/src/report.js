// hilbench report: turns each figure's JSON (in a non-executed script element of class hil-data, written by
// report.cpp) into a Dygraph (Debian's libjs-dygraphs, inlined before this script). Dygraphs does
// the drawing, the axes, box zoom, shift+drag pan, double-click reset and the hover read-out; this
// layer adds what a report needs on top: series styles, bands and reference lines, linked x zoom and
// cursor within a group, wheel zoom, a legend that hides series, grouped bars (a dygraphs plotter)
// and sortable tables.
// For tests: each plot's canvas gets class hil-plot, data-rendered="1", data-ink (pixels the data
// drew on the first draw) and data-empty="1" without data; <body> gets data-plots,
// data-plot-errors and data-plot-error-first; window.hilReport.charts lists the charts.
(function () {
  'use strict';

  const PALETTE = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22', '#17becf'];
  const stats = { plots: 0, errors: 0, first: '' };
  const charts = [];
  const groups = new Map();  // group name -> charts sharing x zoom and the hover cursor

  function esc(s) {
    return String(s).replace(/[&<>"']/g, c => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
  }

  // Read-out value: 6 significant digits, no trailing zeros.
  function fmtVal(v) {
    if (v === null || v === undefined || !isFinite(v)) return '\u2014';
    const a = Math.abs(v);
    if (a !== 0 && (a >= 1e7 || a < 1e-4)) return v.toExponential(4).replace('e+', 'e');
    return String(Number(v.toPrecision(6)));
  }

  // Log-axis tick label: 3 significant digits, exponent form outside 0.001 to 1e5 ("4e-4").
  function fmtLogTick(v) {
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2).replace(/\.?0+e/, 'e').replace('e+', 'e');
    return String(Number(v.toPrecision(3)));
  }

  // Dygraph wants one table: a row per x, a column per series. Entries of all series sorted by x
  // fill rows; a series without a value at a row's x gets null, which connectSeparatedPoints skips,
  // and a gap in a series (NaN or null in the JSON) is NaN, which dygraphs draws as a break.
  // On a log axis, values <= 0 are left out.
  function toRows(series, xLog, yLog) {
    const n = series.length, entries = [];
    series.forEach((s, j) => {
      const len = Math.min(s.x.length, s.y.length);
      for (let k = 0; k < len; k++) {
        let x = s.x[k], y = s.y[k];
        if (x === null || !isFinite(x) || (xLog && x <= 0)) continue;
        if (y === null || !isFinite(y)) y = NaN;
        else if (yLog && y <= 0) continue;
        entries.push([x, j, y, k]);
      }
    });
    entries.sort((a, b) => a[0] - b[0] || a[1] - b[1] || a[3] - b[3]);
    const rows = [];
    let row = null;
    for (const [x, j, y] of entries) {
      if (!row || row[0] !== x || row[j + 1] !== null) {
        row = new Array(n + 1).fill(null);
        row[0] = x;
        rows.push(row);
      }
      row[j + 1] = y;
    }
    return rows;
  }

  function lowerBound(rows, x) {  // first row index with rows[i][0] >= x
    let lo = 0, hi = rows.length;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (rows[mid][0] < x) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  // Counts the pixels of the plot area that the data drew: the canvas before the series are drawn
  // (grid and axes already there) against after. Only on a chart's first draw: reading pixels back
  // costs more than drawing.
  function inkCounter(chart) {
    let before = null, box = null;
    return {
      toString: () => 'hil ink counter',
      activate: () => ({
        willDrawChart: e => {
          e.canvas.classList.add('hil-plot');
          if (chart.empty) e.canvas.setAttribute('data-empty', '1');
          if (!chart.countInk) return;
          const a = e.dygraph.getArea(), r = e.canvas.width / (parseFloat(e.canvas.style.width) || e.canvas.width);
          box = [Math.floor(a.x * r), Math.floor(a.y * r), Math.max(1, Math.floor(a.w * r)), Math.max(1, Math.floor(a.h * r))];
          before = new Uint32Array(e.drawingContext.getImageData(...box).data.buffer);
        },
        didDrawChart: e => {
          e.canvas.setAttribute('data-rendered', '1');
          if (!chart.countInk || !before) return;
          chart.countInk = false;
          const after = new Uint32Array(e.drawingContext.getImageData(...box).data.buffer);
          let ink = 0;
          for (let i = 0; i < after.length; i++) if (after[i] !== before[i]) ink++;
          e.canvas.setAttribute('data-ink', String(ink));
          before = null;
        },
      }),
    };
  }

  // Wheel zoom around the cursor in x: ctrl/cmd+wheel always, plain wheel once the plot has been
  // clicked (so scrolling the page past plots does not zoom them).
  function withWheel(chart, model) {
    return Object.assign({}, model, {
      mousedown: (e, g, ctx) => { activate(chart); model.mousedown(e, g, ctx); },
      wheel: (e, g) => {
        if (!(chart.active || e.ctrlKey || e.metaKey)) return;
        e.preventDefault();
        const dy = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaMode === 2 ? e.deltaY * 400 : e.deltaY;
        const f = Math.exp(Math.max(-400, Math.min(400, dy)) * 0.0015);
        const log = chart.spec.xLog, t = v => (log ? Math.log10(v) : v), u = v => (log ? Math.pow(10, v) : v);
        const [x0, x1] = g.xAxisRange().map(t);
        const area = g.getArea(), rect = g.graphDiv.getBoundingClientRect();
        const fx = Math.max(0, Math.min(1, (e.clientX - rect.left - area.x) / area.w));
        const c = x0 + fx * (x1 - x0);
        g.updateOptions({ dateWindow: [u(c - (c - x0) * f), u(c + (x1 - c) * f)] });
      },
    });
  }

  function activate(chart) {
    for (const c of charts) if (c !== chart && c.active) { c.active = false; c.fig.classList.remove('hil-active'); }
    chart.active = true;
    chart.fig.classList.add('hil-active');
  }

  // Legend buttons: click hides or shows a series, double-click shows it alone (again: all).
  function legend(chart, items) {
    const bar = chart.fig.querySelector('.hil-legend');
    for (const s of items) {
      const b = document.createElement(s.toggles ? 'button' : 'span');
      b.className = 'hil-lg' + (s.toggles ? '' : ' static');
      const sw = document.createElement('span');
      sw.className = 'hil-sw ' + s.kind;
      if (s.kind === 'dashed' || s.kind === '') sw.style.borderTopColor = s.color; else sw.style.background = s.color;
      b.append(sw, document.createTextNode(s.name));
      bar.append(b);
      if (!s.toggles) continue;
      s.button = b;
      b.type = 'button';
      b.title = 'click: hide/show, double-click: show only this' + (s.note || '');
      const apply = () => items.forEach(o => {
        if (!o.toggles) return;
        o.button.classList.toggle('off', o.hidden);
        chart.graph.setVisibility(o.index, !o.hidden);
      });
      b.addEventListener('click', () => { s.hidden = !s.hidden; apply(); });
      b.addEventListener('dblclick', () => {
        const alone = items.every(o => !o.toggles || o === s || o.hidden);
        items.forEach(o => { if (o.toggles) o.hidden = alone ? false : o !== s; });
        apply();
      });
    }
  }

  function makeChart(fig, spec) {
    const chart = { fig, spec, kind: spec.kind, group: spec.group || '', countInk: true, active: false };
    const legendBar = document.createElement('div');
    legendBar.className = 'hil-legend';
    const div = document.createElement('div');
    div.className = 'hil-graph';
    const reset = document.createElement('button');
    reset.type = 'button';
    reset.className = 'hil-reset';
    reset.textContent = 'reset zoom';
    reset.title = 'or double-click the plot';
    const wrap = document.createElement('div');
    wrap.className = 'hil-canvas';
    wrap.append(div, reset);
    fig.append(legendBar, wrap);
    chart.resetButton = reset;
    chart.div = div;
    return chart;
  }

  // Read-out shown next to the cursor: x with its axis name, then every visible series.
  function readout(chart, xName, xText) {
    return data => {
      if (data.x === undefined || data.x === null) return '';
      const rows = data.series.filter(s => s.isVisible).map((s, i) => {
        const item = chart.items[chart.labels.indexOf(s.label)] || chart.items[i];
        return '<span class="hil-sw ' + item.kind + '" style="' + (item.kind === 'dashed' || item.kind === '' ? 'border-top-color:' : 'background:') +
          item.color + '"></span>' + esc(item.name) + '<span class="v">' + fmtVal(s.y) + '</span>';
      });
      const bands = (chart.spec.bands || []).filter(b => b.label && data.x >= Math.min(b.x0, b.x1) && data.x <= Math.max(b.x0, b.x1));
      for (const b of bands) rows.push('<span class="band">\u25A0 ' + esc(b.label) + '</span>');
      return '<div class="hd">' + esc(xName) + ' = ' + esc(xText(data.x)) + '</div>' + (rows.length ? rows.join('<br>') : 'no value here');
    };
  }

  // A zoom, pan or reset in one chart of a group moves the others; the hover cursor follows too.
  function link(chart) {
    if (!chart.group) return;
    if (!groups.has(chart.group)) groups.set(chart.group, []);
    groups.get(chart.group).push(chart);
  }
  let syncing = false;
  function onDraw(chart) {
    return (g, initial) => {
      // An empty plot's fixed y range is not a zoom.
      chart.resetButton.style.visibility = g.isZoomed('x') || (!chart.empty && g.isZoomed('y')) ? 'visible' : 'hidden';
      if (initial || syncing || !chart.group) return;
      syncing = true;
      try {
        const range = g.isZoomed('x') ? g.xAxisRange() : null;
        for (const other of groups.get(chart.group)) {
          if (other === chart || !other.graph) continue;
          const mine = other.graph.isZoomed('x') ? other.graph.xAxisRange() : null;
          if (range === mine || (range && mine && range[0] === mine[0] && range[1] === mine[1])) continue;
          other.graph.updateOptions({ dateWindow: range });
        }
      } finally {
        syncing = false;
      }
    };
  }
  function hoverLinked(chart, x) {
    if (!chart.group) return;
    for (const other of groups.get(chart.group)) {
      if (other === chart || !other.graph || !other.rows.length) continue;
      if (x === null) { other.graph.clearSelection(); continue; }
      let k = lowerBound(other.rows, x);
      if (k > 0 && (k >= other.rows.length || x - other.rows[k - 1][0] < other.rows[k][0] - x)) k--;
      other.graph.setSelection(k, undefined, false);
    }
  }

  // Bands (failing windows) and horizontal reference lines, under the data.
  function underlay(chart) {
    return (ctx, area, g) => {
      ctx.save();
      for (const b of chart.spec.bands || []) {
        const a = g.toDomXCoord(Math.min(b.x0, b.x1)), c = g.toDomXCoord(Math.max(b.x0, b.x1));
        ctx.fillStyle = b.color || '#d62728';
        ctx.globalAlpha = 0.12;
        ctx.fillRect(Math.max(area.x, a), area.y, Math.min(area.x + area.w, c) - Math.max(area.x, a), area.h);
      }
      ctx.globalAlpha = 1;
      ctx.strokeStyle = '#5b6475';
      ctx.fillStyle = '#5b6475';
      ctx.font = '11px sans-serif';
      for (const h of chart.spec.hlines || []) {
        if (chart.spec.yLog && !(h.y > 0)) continue;
        const y = Math.round(g.toDomYCoord(h.y)) + 0.5;
        if (y < area.y || y > area.y + area.h) continue;
        ctx.setLineDash(h.dashed === false ? [] : [5, 4]);
        ctx.beginPath();
        ctx.moveTo(area.x, y);
        ctx.lineTo(area.x + area.w, y);
        ctx.stroke();
        if (h.label) ctx.fillText(h.label, area.x + 4, y - 3);
      }
      ctx.restore();
    };
  }

  const COMMON = {
    connectSeparatedPoints: true,
    animatedZooms: false,
    legend: 'follow',
    gridLineColor: '#e8ebf0',
    axisLineColor: '#c3cad6',
    axisLabelFontSize: 12,
    xLabelHeight: 16,
    yLabelWidth: 16,
    highlightCircleSize: 3.5,
    resizable: 'passive',
  };

  function plot(fig, spec) {
    const chart = makeChart(fig, spec);
    const series = spec.series || [];
    chart.items = series.map((s, i) => ({
      index: i, name: s.name || 'series ' + (i + 1), color: s.color || PALETTE[i % PALETTE.length], hidden: false, toggles: true,
      kind: s.style === 'points' ? 'dot' : s.dashed ? 'dashed' : '',
      note: s.n > s.x.length ? ' (' + s.n.toLocaleString('en') + ' points, drawn as ' + s.x.length + ')' : '',
    }));
    chart.labels = series.map((s, i) => 's' + i);  // names may repeat or hold markup; labels must not
    chart.rows = toRows(series, spec.xLog, spec.yLog);
    const empty = (chart.empty = !chart.rows.some(r => r.slice(1).some(v => v !== null && isFinite(v))));
    const opts = {};
    series.forEach((s, i) => {
      const o = { color: chart.items[i].color, strokeWidth: 1.25 };
      if (s.style === 'step') o.stepPlot = true;
      if (s.style === 'points') Object.assign(o, { drawPoints: true, strokeWidth: 0, pointSize: 1.8 });
      if (s.dashed) o.strokePattern = [6, 4];
      opts[chart.labels[i]] = o;
    });
    const items = chart.items.slice();
    if (series.length === 1 && !series[0].name) items.length = 0;
    const seen = new Set();
    for (const b of spec.bands || []) {
      if (!b.label || seen.has(b.label)) continue;
      seen.add(b.label);
      items.push({ name: b.label, color: b.color || 'rgba(214,39,40,0.3)', kind: 'box', toggles: false });
    }
    chart.div.style.height = (spec.height || 260) + 'px';
    link(chart);
    const xText = v => fmtVal(v);
    chart.graph = new Dygraph(chart.div, empty ? [[0, ...series.map(() => null)], [1, ...series.map(() => null)]] : chart.rows,
      Object.assign({}, COMMON, {
        labels: ['x', ...chart.labels],
        series: opts,
        xlabel: esc(spec.xLabel || ''),
        ylabel: esc(spec.yLabel || ''),
        axes: { x: Object.assign({ logscale: !!spec.xLog }, spec.xLog ? { axisLabelFormatter: fmtLogTick } : {}),
          y: Object.assign({ logscale: !!spec.yLog }, spec.yLog ? { axisLabelFormatter: fmtLogTick } : {}) },
        valueRange: empty ? [0, 1] : null,
        legendFormatter: readout(chart, spec.xLabel || 'x', xText),
        underlayCallback: underlay(chart),
        drawCallback: onDraw(chart),
        highlightCallback: (e, x) => hoverLinked(chart, x),
        unhighlightCallback: () => hoverLinked(chart, null),
        interactionModel: withWheel(chart, Dygraph.defaultInteractionModel),
        plugins: [inkCounter(chart)],
      }));
    legend(chart, items);
    chart.resetButton.addEventListener('click', () => chart.graph.resetZoom());
    if (empty) {
      const note = document.createElement('div');
      note.className = 'hil-nodata';
      note.textContent = 'no data';
      chart.div.parentNode.append(note);
    }
    return chart;
  }

  // Grouped bars: category i at x = i, one bar per visible group side by side, values above the
  // bars when they have room. The dygraphs plotter option; every group drawn by the first call.
  function barPlotter(chart) {
    return e => {
      if (e.seriesIndex !== 0) return;
      const g = e.dygraph, ctx = e.drawingContext, sets = e.allSeriesPoints;
      const slot = g.toDomXCoord(1) - g.toDomXCoord(0), inner = slot * 0.78, bw = inner / Math.max(1, sets.length);
      const y0 = g.toDomYCoord(0);
      const room = bw >= 30 && chart.spec.categories.length * sets.length <= 48;
      ctx.font = '11px sans-serif';
      ctx.textAlign = 'center';
      sets.forEach((points, j) => {
        for (const p of points) {
          if (p.yval === null || !isFinite(p.yval)) continue;
          const x = p.canvasx - inner / 2 + j * bw;
          ctx.fillStyle = chart.items[chart.labels.indexOf(p.name)].color;
          ctx.fillRect(x + 0.5, Math.min(p.canvasy, y0), Math.max(1, bw - 1), Math.max(1, Math.abs(y0 - p.canvasy)));
          if (!room) continue;
          ctx.fillStyle = '#4a5263';
          ctx.textBaseline = p.yval >= 0 ? 'bottom' : 'top';
          ctx.fillText(fmtVal(Number(p.yval.toPrecision(3))), x + bw / 2, p.yval >= 0 ? p.canvasy - 2 : p.canvasy + 2);
        }
      });
    };
  }

  function bars(fig, spec) {
    const chart = makeChart(fig, spec);
    const cats = spec.categories || [], grs = spec.groups || [];
    chart.cats = cats;
    chart.items = grs.map((gr, i) => ({ index: i, name: gr.name || 'group ' + (i + 1), color: PALETTE[i % PALETTE.length],
      kind: 'box', hidden: false, toggles: true }));
    chart.labels = grs.map((gr, i) => 'g' + i);
    chart.rows = cats.map((c, i) => [i, ...grs.map(gr => (gr.values[i] === null ? NaN : gr.values[i]))]);
    const empty = (chart.empty = !chart.rows.some(r => r.slice(1).some(v => isFinite(v))));
    chart.div.style.height = (spec.height || 260) + 'px';
    // Each category's label gets its slot's width and wraps in it.
    const slot = Math.max(30, ((fig.clientWidth || 600) - 70) / Math.max(1, cats.length));
    const name = i => cats[Math.round(i)] === undefined ? '' : cats[Math.round(i)];
    chart.graph = new Dygraph(chart.div, chart.rows.length ? chart.rows : [[0, ...grs.map(() => null)]], Object.assign({}, COMMON, {
      labels: ['category', ...chart.labels],
      colors: chart.items.map(it => it.color),
      ylabel: esc(spec.yLabel || ''),
      includeZero: true,
      valueRange: empty ? [0, 1] : null,
      dateWindow: [-0.5, Math.max(0.5, cats.length - 0.5)],
      plotter: barPlotter(chart),
      xAxisHeight: 46,
      axes: { x: { drawGrid: false, pixelsPerLabel: 1,
        ticker: () => cats.map((c, i) => ({ v: i, label: '<span title="' + esc(c) + '">' + esc(c.length > 28 ? c.slice(0, 27) + '\u2026' : c) + '</span>' })),
        axisLabelWidth: slot } },
      legendFormatter: readout(chart, 'category', name),
      interactionModel: { dblclick: () => {} },  // categories: nothing to zoom or pan
      drawCallback: g => { chart.resetButton.style.visibility = 'hidden'; },
      plugins: [inkCounter(chart)],
    }));
    legend(chart, grs.length > 1 || (grs.length === 1 && grs[0].name) ? chart.items : []);
    return chart;
  }

  // ---------- tables: click a header to sort ----------

  function sortable(table) {
    const heads = table.querySelectorAll('thead th');
    heads.forEach((th, col) => th.addEventListener('click', () => {
      const body = table.tBodies[0];
      if (!body) return;
      const rows = Array.from(body.rows);
      const cell = r => (r.cells[col] ? r.cells[col].textContent.trim() : '');
      const numeric = rows.every(r => cell(r) === '' || isFinite(parseFloat(cell(r))));
      const dir = th.getAttribute('data-sort') === 'asc' ? -1 : 1;
      heads.forEach(h => h.removeAttribute('data-sort'));
      th.setAttribute('data-sort', dir > 0 ? 'asc' : 'desc');
      rows.sort((a, b) => {
        const x = cell(a), y = cell(b);
        if (numeric) return dir * ((parseFloat(x) || 0) - (parseFloat(y) || 0));
        return dir * x.localeCompare(y, undefined, { numeric: true });
      });
      for (const r of rows) body.append(r);
    }));
  }

  // ---------- start ----------

  function publish() {
    document.body.setAttribute('data-plots', String(stats.plots));
    document.body.setAttribute('data-plot-errors', String(stats.errors));
    if (stats.first) document.body.setAttribute('data-plot-error-first', stats.first);
  }

  function fail(fig, e) {
    stats.errors++;
    if (!stats.first) stats.first = String((e && e.message) || e);
    if (fig && !fig.querySelector('.hil-failed')) {
      const d = document.createElement('div');
      d.className = 'hil-failed';
      d.textContent = 'This plot could not be drawn: ' + ((e && e.message) || e);
      fig.append(d);
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
    document.addEventListener('mousedown', e => {
      if (!e.target.closest || !e.target.closest('.hil-canvas')) {
        for (const c of charts) { c.active = false; c.fig.classList.remove('hil-active'); }
      }
    });
    publish();
  }

  window.addEventListener('error', e => { stats.errors++; if (!stats.first) stats.first = String(e.message); publish(); });
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
