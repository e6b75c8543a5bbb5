// hilbench report: small canvas plotting for offline report.html files, no dependencies.
// Each figure.hil-fig holds its spec as JSON in a non-executed script element (class hil-data),
// written by analysis/report/src/report.cpp; this script turns it into an interactive plot.
// For tests, each plot canvas gets data-rendered="1" and data-ink="<pixels the data drew>", and
// <body> gets data-plots and data-plot-errors (and data-plot-error-first with the first message).
(function () {
  'use strict';

  const PALETTE = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2',
    '#7f7f7f', '#bcbd22', '#17becf'];
  const FONT_FAMILY = 'system-ui, -apple-system, "Segoe UI", Roboto, "Noto Sans", "DejaVu Sans", sans-serif';
  const FONT = '12px ' + FONT_FAMILY;
  const FONT_SMALL = '11px ' + FONT_FAMILY;
  const C = {
    bg: '#ffffff', grid: '#e8ebf0', gridMinor: '#f3f5f8', frame: '#c3cad6', tick: '#8a93a3',
    text: '#4a5263', label: '#1d2433', muted: '#8a93a3', band: '#d62728', hline: '#5b6475',
    select: 'rgba(31,111,235,0.12)', selectEdge: 'rgba(31,111,235,0.6)', cursor: '#6b7385',
  };
  const stats = { plots: 0, errors: 0, first: '' };
  const groups = new Map();  // group name -> plots sharing x zoom and cursor
  const all = [];
  let printDpr = 0;  // > 0 while printing: render sharper than the screen
  let tip = null;

  // ---------- numbers and ticks ----------

  function niceStep(span, target) {
    const raw = span / Math.max(1, target);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const f = raw / mag;
    return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * mag;
  }

  function minus(s) { return s.replace(/^-/, '\u2212').replace('e-', 'e\u2212'); }

  // Tick label with as many decimals as the step needs.
  function fmtTick(v, step) {
    if (Math.abs(v) < step * 1e-6) return '0';
    const a = Math.abs(v);
    if (a >= 1e6 || a < 1e-4) {
      const d = Math.max(0, Math.min(6, Math.floor(Math.log10(a)) - Math.floor(Math.log10(step) + 1e-9)));
      return minus(v.toExponential(d).replace('e+', 'e'));
    }
    return minus(v.toFixed(Math.max(0, Math.min(10, -Math.floor(Math.log10(step) + 1e-9)))));
  }

  // Read-out value: 6 significant digits, no trailing zeros.
  function fmtVal(v) {
    if (v === null || !isFinite(v)) return '\u2014';
    const a = Math.abs(v);
    if (a !== 0 && (a >= 1e7 || a < 1e-4)) return minus(v.toExponential(4).replace('e+', 'e'));
    return minus(String(Number(v.toPrecision(6))));
  }

  const SUP = { '0': '\u2070', '1': '\u00b9', '2': '\u00b2', '3': '\u00b3', '4': '\u2074', '5': '\u2075',
    '6': '\u2076', '7': '\u2077', '8': '\u2078', '9': '\u2079', '-': '\u207b' };
  function fmtPow10(k) {
    if (k >= -3 && k <= 4) return String(Number(Math.pow(10, k).toPrecision(6)));
    return '10' + String(k).split('').map(c => SUP[c]).join('');
  }

  // Ticks in axis space: {v, label, major}. lo/hi are log10 values on a log axis.
  function ticks(lo, hi, log, target) {
    if (!log || hi - lo < 1) {
      const a = log ? Math.pow(10, lo) : lo, b = log ? Math.pow(10, hi) : hi;
      let out = [];
      // A short axis still gets three labels: retry with a finer step.
      for (let t = target; out.length < 3 && t <= target * 8; t *= 2) {
        const step = niceStep(b - a, t);
        out = [];
        const first = Math.ceil(a / step - 1e-9);
        for (let i = first; i * step <= b + step * 1e-9 && out.length < 200; i++) {
          const v = i * step;
          if (log && v <= 0) continue;
          out.push({ v: log ? Math.log10(v) : v, label: fmtTick(v, step), major: true });
        }
      }
      return out;
    }
    const k0 = Math.floor(lo), k1 = Math.ceil(hi), decades = hi - lo;
    const every = Math.max(1, Math.ceil(decades / Math.max(1, target)));
    const out = [];
    for (let k = k0; k <= k1; k++) {
      if (k >= lo - 1e-9 && k <= hi + 1e-9) {
        out.push({ v: k, label: (k % every === 0) ? fmtPow10(k) : '', major: k % every === 0 });
      }
      if (decades > 6) continue;  // minor ticks only when they are not a solid mass
      for (let m = 2; m <= 9; m++) {
        const v = k + Math.log10(m);
        if (v < lo || v > hi) continue;
        const labelled = decades <= 1.5 && (m === 2 || m === 5);
        out.push({ v, label: labelled ? fmtVal(m * Math.pow(10, k)) : '', major: false });
      }
    }
    return out;
  }

  function lowerBound(a, v) {  // first index with a[i] >= v (a sorted)
    let lo = 0, hi = a.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (a[mid] < v) lo = mid + 1; else hi = mid; }
    return lo;
  }

  function clamp(v, lo, hi) { return Math.max(lo, Math.min(hi, v)); }

  function swatch(color, kind) {
    const s = document.createElement('span');
    s.className = 'hil-sw' + (kind ? ' ' + kind : '');
    if (kind === 'dot' || kind === 'box') s.style.background = color;
    else s.style.borderTopColor = color;
    if (kind === 'box band') { s.className = 'hil-sw box'; s.style.background = color; s.style.opacity = 0.3; }
    return s;
  }

  function showTip(html, clientX, clientY) {
    if (!tip) return;
    tip.innerHTML = html;
    tip.hidden = false;
    const w = tip.offsetWidth, h = tip.offsetHeight;
    let x = clientX + 14, y = clientY + 14;
    if (x + w > window.innerWidth - 4) x = clientX - w - 14;
    if (y + h > window.innerHeight - 4) y = clientY - h - 14;
    tip.style.left = Math.max(4, x) + 'px';
    tip.style.top = Math.max(4, y) + 'px';
  }
  function hideTip() { if (tip) tip.hidden = true; }
  function esc(s) {
    return String(s).replace(/[&<>"']/g, c => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
  }
  function tipSwatch(color, kind) {
    const style = (kind === 'dot' || kind === 'box') ? 'background:' + color : 'border-top-color:' + color;
    return '<span class="hil-sw ' + (kind || '') + '" style="' + esc(style) + '"></span>';
  }

  // ---------- a figure's frame: DOM, canvas sizing, legend ----------

  class Chart {
    constructor(fig, spec) {
      this.fig = fig;
      this.spec = spec;
      this.height = spec.height || 260;
      const cap = fig.querySelector('figcaption') || fig.insertBefore(document.createElement('figcaption'), fig.firstChild);
      this.legend = document.createElement('div');
      this.legend.className = 'hil-legend';
      this.wrap = document.createElement('div');
      this.wrap.className = 'hil-canvas';
      this.wrap.style.height = this.height + 'px';
      this.canvas = document.createElement('canvas');
      this.canvas.className = 'hil-plot';
      this.overlay = document.createElement('canvas');
      this.overlay.className = 'hil-overlay';
      this.wrap.append(this.canvas, this.overlay);
      fig.append(this.legend, this.wrap);
      this.caption = cap;
      this.ctx = this.canvas.getContext('2d');
      this.octx = this.overlay.getContext('2d');
      this.cssW = 0;
      this.pending = false;
    }

    // Sizes both canvases for the current width and pixel ratio; returns false if not laid out.
    size() {
      const w = Math.floor(this.wrap.clientWidth || this.fig.clientWidth || 600);
      const dpr = printDpr || window.devicePixelRatio || 1;
      this.cssW = w;
      this.dpr = dpr;
      for (const c of [this.canvas, this.overlay]) {
        const W = Math.round(w * dpr), H = Math.round(this.height * dpr);
        if (c.width !== W || c.height !== H) { c.width = W; c.height = H; }
      }
      this.ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      this.octx.setTransform(dpr, 0, 0, dpr, 0, 0);
      return w > 0;
    }

    // Half-pixel alignment so 1-px lines are crisp at any integer pixel ratio.
    crisp(v) { const d = this.dpr; return (Math.round(v * d) + (Math.round(d) % 2 ? 0.5 : 0)) / d; }

    schedule() {
      if (this.pending) return;
      this.pending = true;
      const run = () => { if (this.pending) { this.pending = false; this.safeRender(false); } };
      requestAnimationFrame(run);
      setTimeout(run, 100);  // headless or hidden pages may not run animation frames
    }

    safeRender(countInk) {
      try { this.render(countInk); } catch (e) { fail(this.fig, e); }
    }

    // Counts the pixels that drawing `draw` changed inside the plot area (the data's ink).
    inked(g, countInk, draw) {
      if (!countInk) { draw(); return; }
      const d = this.dpr, x = Math.floor(g.l * d), y = Math.floor(g.t * d);
      const w = Math.max(1, Math.floor(g.w * d)), h = Math.max(1, Math.floor(g.h * d));
      const before = new Uint32Array(this.ctx.getImageData(x, y, w, h).data.buffer);
      draw();
      const after = new Uint32Array(this.ctx.getImageData(x, y, w, h).data.buffer);
      let ink = 0;
      for (let i = 0; i < after.length; i++) if (after[i] !== before[i]) ink++;
      this.canvas.setAttribute('data-ink', String(ink));
    }

    legendItem(label, color, kind, onToggle, onSolo) {
      const b = document.createElement(onToggle ? 'button' : 'span');
      b.className = 'hil-lg' + (onToggle ? '' : ' static');
      b.append(swatch(color, kind), document.createTextNode(label));
      if (onToggle) {
        b.type = 'button';
        b.title = 'click: hide/show, double-click: show only this';
        b.addEventListener('click', () => onToggle(b));
        b.addEventListener('dblclick', () => onSolo(b));
      }
      this.legend.append(b);
      return b;
    }

    drawText(ctx, text, x, y, align, base, font, color) {
      ctx.font = font || FONT;
      ctx.fillStyle = color || C.text;
      ctx.textAlign = align;
      ctx.textBaseline = base;
      ctx.fillText(text, x, y);
    }

    // Left margin that fits the y tick labels and the rotated y label.
    leftMargin(yt, yLabel) {
      this.ctx.font = FONT;
      let w = 0;
      for (const t of yt) if (t.label) w = Math.max(w, this.ctx.measureText(t.label).width);
      return Math.ceil(w) + 10 + (yLabel ? 20 : 4);
    }

    drawYAxis(g, yt, yLabel) {
      const ctx = this.ctx;
      for (const t of yt) {
        if (!t.label) continue;
        const py = g.Y(t.v);
        if (py < g.t - 1 || py > g.t + g.h + 1) continue;
        this.drawText(ctx, t.label, g.l - 6, py, 'right', 'middle');
      }
      if (yLabel) {
        ctx.save();
        ctx.translate(12, g.t + g.h / 2);
        ctx.rotate(-Math.PI / 2);
        this.drawText(ctx, yLabel, 0, 0, 'center', 'middle', FONT, C.label);
        ctx.restore();
      }
    }

    drawFrame(g) {
      const ctx = this.ctx;
      ctx.strokeStyle = C.frame;
      ctx.lineWidth = 1;
      ctx.setLineDash([]);
      ctx.strokeRect(this.crisp(g.l), this.crisp(g.t), Math.round(g.w), Math.round(g.h));
    }

    drawGrid(g, xt, yt) {
      const ctx = this.ctx;
      ctx.lineWidth = 1;
      ctx.setLineDash([]);
      for (const pass of [false, true]) {  // minor lines first, majors on top
        ctx.strokeStyle = pass ? C.grid : C.gridMinor;
        ctx.beginPath();
        for (const t of yt || []) {
          if (t.major !== pass) continue;
          const py = this.crisp(g.Y(t.v));
          if (py > g.t && py < g.t + g.h) { ctx.moveTo(g.l, py); ctx.lineTo(g.l + g.w, py); }
        }
        for (const t of xt || []) {
          if (t.major !== pass) continue;
          const px = this.crisp(g.X(t.v));
          if (px > g.l && px < g.l + g.w) { ctx.moveTo(px, g.t); ctx.lineTo(px, g.t + g.h); }
        }
        ctx.stroke();
      }
    }

    noData(g) {
      this.drawText(this.ctx, 'no data', g.l + g.w / 2, g.t + g.h / 2, 'center', 'middle', '13px ' + FONT_FAMILY, C.muted);
      this.canvas.setAttribute('data-empty', '1');
    }
  }

  // ---------- line / step / scatter plot ----------

  class Plot extends Chart {
    constructor(fig, spec) {
      super(fig, spec);
      this.xLog = !!spec.xLog;
      this.yLog = !!spec.yLog;
      const toX = v => (v === null ? NaN : this.xLog ? (v > 0 ? Math.log10(v) : NaN) : v);
      const toY = v => (v === null ? NaN : this.yLog ? (v > 0 ? Math.log10(v) : NaN) : v);
      this.series = (spec.series || []).map((s, i) => {
        const n = Math.min(s.x.length, s.y.length);
        const ax = new Float64Array(n), ay = new Float64Array(n);
        let mono = true;
        for (let k = 0; k < n; k++) {
          ax[k] = toX(s.x[k]);
          ay[k] = toY(s.y[k]);
          if (!(ax[k] >= (k ? ax[k - 1] : -Infinity))) mono = false;  // also false on NaN
        }
        return { name: s.name || 'series ' + (i + 1), color: s.color || PALETTE[i % PALETTE.length],
          style: s.style || 'line', dashed: !!s.dashed, n: s.n, ax, ay, mono, hidden: false };
      });
      this.bands = (spec.bands || []).map(b => ({ a: toX(Math.min(b.x0, b.x1)), b: toX(Math.max(b.x0, b.x1)),
        label: b.label || '', color: b.color || C.band }));
      this.hlines = (spec.hlines || []).map(h => ({ v: toY(h.y), y: h.y, label: h.label || '', dashed: h.dashed !== false }));
      this.fullX = this.computeFullX();
      this.view = null;   // [x0, x1] in axis space while zoomed
      this.yView = null;  // [y0, y1] while the y axis was wheel-zoomed or panned
      this.cursor = null; // axis-space x of the hover cursor (also shown for linked plots)
      this.sel = null;    // [px0, px1] box being dragged
      this.group = spec.group || '';
      if (this.group) {
        if (!groups.has(this.group)) groups.set(this.group, []);
        groups.get(this.group).push(this);
      }
      this.buildLegend();
      this.addReset();
      this.listen();
    }

    buildLegend() {
      const named = this.series.length > 1 || (this.series.length === 1 && this.spec.series[0].name);
      if (named) {
        for (const s of this.series) {
          const kind = s.style === 'points' ? 'dot' : s.dashed ? 'dashed' : '';
          s.button = this.legendItem(s.name, s.color, kind, b => {
            s.hidden = !s.hidden;
            b.classList.toggle('off', s.hidden);
            this.schedule();
          }, () => {
            const alone = this.series.every(o => o === s || o.hidden);
            for (const o of this.series) {
              o.hidden = alone ? false : o !== s;
              o.button.classList.toggle('off', o.hidden);
            }
            this.schedule();
          });
          if (s.n > s.ax.length) s.button.title += ' (' + s.n.toLocaleString('en') + ' points, drawn as ' + s.ax.length + ')';
        }
      }
      const seen = new Set();
      for (const b of this.bands) {
        if (!b.label || seen.has(b.label)) continue;
        seen.add(b.label);
        this.legendItem(b.label, b.color, 'box band');
      }
    }

    addReset() {
      const r = document.createElement('button');
      r.type = 'button';
      r.className = 'hil-reset';
      r.textContent = 'reset zoom';
      r.title = 'or double-click the plot';
      r.addEventListener('click', () => this.reset());
      this.wrap.append(r);
      this.resetButton = r;
    }

    computeFullX() {
      let lo = Infinity, hi = -Infinity, pad = 0;
      for (const s of this.series) {
        for (let k = 0; k < s.ax.length; k++) {
          const v = s.ax[k];
          if (v < lo) lo = v;
          if (v > hi) hi = v;
        }
        if (s.style === 'points') pad = 0.03;
      }
      if (!(hi >= lo)) {
        for (const b of this.bands) { lo = Math.min(lo, b.a); hi = Math.max(hi, b.b); }
      }
      if (!(hi >= lo)) return this.xLog ? [0, 1] : [0, 1];
      if (hi === lo) return [lo - (Math.abs(lo) * 0.05 || 0.5), hi + (Math.abs(hi) * 0.05 || 0.5)];
      return [lo - pad * (hi - lo), hi + pad * (hi - lo)];
    }

    xRange() { return this.view || this.fullX; }

    // y extent of what is visible in x range [x0, x1], padded; null if nothing is.
    autoY(x0, x1) {
      let lo = Infinity, hi = -Infinity;
      for (const s of this.series) {
        if (s.hidden) continue;
        let i0 = 0, i1 = s.ax.length;
        if (s.mono) {
          i0 = Math.max(0, lowerBound(s.ax, x0) - (s.style === 'points' ? 0 : 1));
          i1 = Math.min(s.ax.length, lowerBound(s.ax, x1) + 1);
        }
        for (let k = i0; k < i1; k++) {
          const v = s.ay[k];
          if (!s.mono && !(s.ax[k] >= x0 && s.ax[k] <= x1)) continue;
          if (v < lo) lo = v;
          if (v > hi) hi = v;
        }
      }
      if (!(hi >= lo)) return null;
      for (const h of this.hlines) {
        if (isFinite(h.v)) { lo = Math.min(lo, h.v); hi = Math.max(hi, h.v); }
      }
      if (hi === lo) {
        const d = this.yLog ? 0.5 : Math.abs(lo) * 0.1 || 1;
        return [lo - d, hi + d];
      }
      const pad = (hi - lo) * 0.06;
      return [lo - pad, hi + pad];
    }

    render(countInk) {
      if (!this.size()) return;
      const ctx = this.ctx, W = this.cssW, H = this.height;
      ctx.clearRect(0, 0, W, H);
      ctx.fillStyle = C.bg;
      ctx.fillRect(0, 0, W, H);
      const [x0, x1] = this.xRange();
      const auto = this.autoY(x0, x1);
      const empty = !this.series.some(s => s.ay.some(v => isFinite(v)));
      let [y0, y1] = this.yView || auto || this.lastY || [0, 1];
      if (!(y1 > y0)) { y0 -= 0.5; y1 += 0.5; }
      this.lastY = [y0, y1];
      const hasBandLabels = this.bands.some(b => b.label);
      const t = hasBandLabels ? 20 : 10, b = 40;
      const h = Math.max(20, H - t - b);
      const yt = ticks(y0, y1, this.yLog, Math.max(2, Math.floor(h / 42)));
      const l = this.leftMargin(yt, this.spec.yLabel);
      const w = Math.max(20, W - l - 16);
      const g = { l, t, w, h, x0, x1, y0, y1, sx: w / (x1 - x0), sy: h / (y1 - y0) };
      g.X = v => g.l + (v - g.x0) * g.sx;
      g.Y = v => g.t + g.h - (v - g.y0) * g.sy;
      this.g = g;
      const xt = this.xTicks(g);

      this.drawGrid(g, xt, yt);
      ctx.save();
      ctx.beginPath();
      ctx.rect(l, t, w, h);
      ctx.clip();
      this.drawBands(g);
      this.drawHLines(g);
      this.inked(g, countInk, () => { for (const s of this.series) if (!s.hidden) this.drawSeries(g, s); });
      this.drawHLineLabels(g);
      ctx.restore();
      this.drawFrame(g);
      this.drawXAxis(g, xt);
      this.drawYAxis(g, yt, this.spec.yLabel);
      this.drawBandLabels(g);
      if (empty) this.noData(g);
      this.canvas.setAttribute('data-rendered', '1');
      this.resetButton.style.visibility = this.view || this.yView ? 'visible' : 'hidden';
      this.drawOverlay();
    }

    // x ticks spaced so that the widest label fits, with a gap.
    xTicks(g) {
      this.ctx.font = FONT;
      let target = Math.max(2, Math.floor(g.w / 80));
      let xt = [];
      for (let tries = 0; tries < 4; tries++) {
        xt = ticks(g.x0, g.x1, this.xLog, target);
        const labelled = xt.filter(t => t.label);
        let widest = 0;
        for (const t of labelled) widest = Math.max(widest, this.ctx.measureText(t.label).width);
        const space = labelled.length > 1 ? g.w / labelled.length : g.w;
        if (widest + 14 <= space || target <= 2) break;
        target = Math.max(2, Math.floor(g.w / (widest + 20)));
      }
      return xt;
    }

    drawXAxis(g, xt) {
      const ctx = this.ctx;
      ctx.strokeStyle = C.tick;
      ctx.lineWidth = 1;
      ctx.beginPath();
      const yb = g.t + g.h;
      for (const t of xt) {
        const px = g.X(t.v);
        if (px < g.l - 0.5 || px > g.l + g.w + 0.5) continue;
        const cx = this.crisp(px);
        ctx.moveTo(cx, yb);
        ctx.lineTo(cx, yb + (t.major ? 4 : 2));
        if (t.label) this.drawText(ctx, t.label, px, yb + 6, 'center', 'top');
      }
      ctx.stroke();
      if (this.spec.xLabel) this.drawText(ctx, this.spec.xLabel, g.l + g.w / 2, this.height - 4, 'center', 'bottom', FONT, C.label);
    }

    drawBands(g) {
      const ctx = this.ctx;
      for (const b of this.bands) {
        if (!(b.b >= g.x0 && b.a <= g.x1)) continue;
        const a = clamp(g.X(b.a), g.l - 1, g.l + g.w + 1), e = clamp(g.X(b.b), g.l - 1, g.l + g.w + 1);
        ctx.globalAlpha = 0.13;
        ctx.fillStyle = b.color;
        ctx.fillRect(a, g.t, Math.max(1, e - a), g.h);
        ctx.globalAlpha = 0.45;
        ctx.fillRect(a, g.t, Math.max(1, e - a), 2);
        ctx.globalAlpha = 1;
      }
    }

    drawBandLabels(g) {
      const ctx = this.ctx;
      ctx.font = FONT_SMALL;
      let end = -Infinity;
      for (const b of this.bands) {
        if (!b.label || !(b.b >= g.x0 && b.a <= g.x1)) continue;
        const a = Math.max(g.X(b.a), g.l), e = Math.min(g.X(b.b), g.l + g.w);
        const tw = ctx.measureText(b.label).width;
        const x = Math.min(Math.max(a, g.l), g.l + g.w - tw);
        if (x < end + 6 || tw > Math.max(e - a, 0) + 60) continue;  // would overlap or stray far
        this.drawText(ctx, b.label, x, g.t - 4, 'left', 'bottom', FONT_SMALL, b.color);
        end = x + tw;
      }
    }

    drawHLines(g) {
      const ctx = this.ctx;
      for (const hl of this.hlines) {
        if (!isFinite(hl.v) || hl.v < g.y0 || hl.v > g.y1) continue;
        const py = this.crisp(g.Y(hl.v));
        ctx.strokeStyle = C.hline;
        ctx.lineWidth = 1;
        ctx.setLineDash(hl.dashed ? [5, 4] : []);
        ctx.beginPath();
        ctx.moveTo(g.l, py);
        ctx.lineTo(g.l + g.w, py);
        ctx.stroke();
        ctx.setLineDash([]);
      }
    }

    // Labels go over the data, on a white halo, so dense data cannot hide them.
    drawHLineLabels(g) {
      const ctx = this.ctx;
      ctx.font = FONT_SMALL;
      ctx.textAlign = 'right';
      ctx.lineJoin = 'round';
      for (const hl of this.hlines) {
        if (!hl.label || !isFinite(hl.v) || hl.v < g.y0 || hl.v > g.y1) continue;
        const py = g.Y(hl.v);
        const up = py - g.t > 16;
        ctx.textBaseline = up ? 'bottom' : 'top';
        const ty = up ? py - 2 : py + 3;
        ctx.lineWidth = 3;
        ctx.strokeStyle = 'rgba(255,255,255,0.9)';
        ctx.strokeText(hl.label, g.l + g.w - 6, ty);
        ctx.fillStyle = C.hline;
        ctx.fillText(hl.label, g.l + g.w - 6, ty);
      }
    }

    visibleRange(s, g) {
      if (!s.mono) return [0, s.ax.length];
      return [Math.max(0, lowerBound(s.ax, g.x0) - 1), Math.min(s.ax.length, lowerBound(s.ax, g.x1) + 1)];
    }

    drawSeries(g, s) {
      const ctx = this.ctx;
      const [i0, i1] = this.visibleRange(s, g);
      const lim = 1e5;  // keeps far off-screen coordinates finite for the rasteriser
      const X = v => clamp(g.X(v), -lim, lim), Y = v => clamp(g.Y(v), -lim, lim);
      if (s.style === 'points') {
        ctx.fillStyle = s.color;
        const r = (i1 - i0) > 3000 ? 1.5 : 2.5;
        ctx.beginPath();
        for (let k = i0; k < i1; k++) {
          if (!isFinite(s.ax[k]) || !isFinite(s.ay[k])) continue;
          const px = X(s.ax[k]), py = Y(s.ay[k]);
          ctx.moveTo(px + r, py);
          ctx.arc(px, py, r, 0, 2 * Math.PI);
        }
        ctx.globalAlpha = 0.8;
        ctx.fill();
        ctx.globalAlpha = 1;
        return;
      }
      ctx.strokeStyle = s.color;
      ctx.lineWidth = 1.5;
      ctx.lineJoin = 'round';
      ctx.setLineDash(s.dashed ? [6, 4] : []);
      ctx.beginPath();
      let lastX = 0, lastY = 0, run = 0;  // run: points since the last gap
      const single = [];
      for (let k = i0; k < i1; k++) {
        if (!isFinite(s.ax[k]) || !isFinite(s.ay[k])) {
          if (s.style === 'step' && run > 0 && isFinite(s.ax[k])) ctx.lineTo(X(s.ax[k]), lastY);  // held until the gap
          else if (run === 1) single.push([lastX, lastY]);
          run = 0;
          continue;
        }
        const px = X(s.ax[k]), py = Y(s.ay[k]);
        if (run === 0) ctx.moveTo(px, py);
        else if (s.style === 'step') { ctx.lineTo(px, lastY); ctx.lineTo(px, py); }
        else ctx.lineTo(px, py);
        lastX = px; lastY = py; run++;
      }
      if (run === 1) single.push([lastX, lastY]);
      ctx.stroke();
      ctx.setLineDash([]);
      if (single.length) {  // an isolated sample between gaps would be invisible as a line
        ctx.fillStyle = s.color;
        for (const [px, py] of single) ctx.fillRect(px - 1.5, py - 1.5, 3, 3);
      }
    }

    // ----- interaction -----

    linked() { return this.group ? groups.get(this.group).filter(p => p.xLog === this.xLog) : [this]; }

    setView(view) {
      for (const p of this.linked()) {
        p.view = view ? view.slice() : null;
        if (!view) p.yView = null;
        p.schedule();
      }
    }

    reset() { this.setView(null); }

    zoomX(center, factor) {
      const [a, b] = this.xRange();
      const full = this.fullX[1] - this.fullX[0];
      let span = clamp((b - a) * factor, full * 1e-7, full * 20);
      const f = (center - a) / (b - a);
      this.setView([center - f * span, center + (1 - f) * span]);
    }

    zoomY(center, factor) {
      const [a, b] = this.yView || this.lastY;
      const span = (b - a) * factor, f = (center - a) / (b - a);
      this.yView = [center - f * span, center + (1 - f) * span];
      this.schedule();
    }

    local(e) {
      const r = this.overlay.getBoundingClientRect();
      return [e.clientX - r.left, e.clientY - r.top];
    }

    inPlot(mx, my) { const g = this.g; return g && mx >= g.l && mx <= g.l + g.w && my >= g.t && my <= g.t + g.h; }

    listen() {
      const o = this.overlay;
      let drag = null;
      o.addEventListener('pointerdown', e => {
        const [mx, my] = this.local(e);
        if (!this.g || (e.button !== 0 && e.button !== 1)) return;
        this.wrap.classList.add('hil-active');
        this.active = true;
        const pan = e.shiftKey || e.button === 1;
        if (!pan && !this.inPlot(mx, my)) return;
        drag = { mode: pan ? 'pan' : 'zoom', mx, my, view: this.xRange().slice(), yv: this.yView && this.yView.slice() };
        o.setPointerCapture(e.pointerId);
        e.preventDefault();
      });
      o.addEventListener('pointermove', e => {
        const [mx, my] = this.local(e);
        const g = this.g;
        if (!g) return;
        if (drag && drag.mode === 'zoom') {
          this.sel = [clamp(drag.mx, g.l, g.l + g.w), clamp(mx, g.l, g.l + g.w)];
          this.drawOverlay();
          hideTip();
          return;
        }
        if (drag && drag.mode === 'pan') {
          const dx = (mx - drag.mx) / g.sx;
          this.setView([drag.view[0] - dx, drag.view[1] - dx]);
          if (drag.yv) { const dy = (my - drag.my) / g.sy; this.yView = [drag.yv[0] + dy, drag.yv[1] + dy]; }
          return;
        }
        this.hover(mx, my, e);
      });
      const end = e => {
        if (!drag) return;
        const d = drag;
        drag = null;
        if (d.mode === 'zoom' && this.sel) {
          const [a, b] = this.sel;
          this.sel = null;
          const g = this.g;
          if (Math.abs(b - a) >= 5) {
            const va = g.x0 + (Math.min(a, b) - g.l) / g.sx, vb = g.x0 + (Math.max(a, b) - g.l) / g.sx;
            this.setView([va, vb]);
          } else this.drawOverlay();
        }
        try { o.releasePointerCapture(e.pointerId); } catch (_) { /* already released */ }
      };
      o.addEventListener('pointerup', end);
      o.addEventListener('pointercancel', end);
      o.addEventListener('pointerleave', () => {
        if (drag) return;
        this.active = false;
        this.wrap.classList.remove('hil-active');
        for (const p of this.linked()) { p.cursor = null; p.drawOverlay(); }
        hideTip();
      });
      o.addEventListener('dblclick', e => { e.preventDefault(); this.reset(); });
      o.addEventListener('wheel', e => {
        // Plain wheel scrolls the page until the plot is clicked; ctrl/cmd+wheel always zooms.
        if (!(this.active || e.ctrlKey || e.metaKey) || !this.g) return;
        e.preventDefault();
        const [mx, my] = this.local(e);
        const g = this.g;
        const dy = e.deltaMode === 1 ? e.deltaY * 33 : e.deltaMode === 2 ? e.deltaY * 400 : e.deltaY;
        const factor = Math.exp(clamp(dy, -400, 400) * 0.0015);
        if (mx < g.l) this.zoomY(g.y0 + (g.t + g.h - my) / g.sy, factor);
        else this.zoomX(g.x0 + (clamp(mx, g.l, g.l + g.w) - g.l) / g.sx, factor);
      }, { passive: false });
    }

    // What series s reads at axis-space x: {x, y} in axis space (y NaN inside a gap), or null.
    // Lines interpolate and steps hold, so the read-out is the drawn curve at the cursor; scatter
    // and curves that double back snap to the nearest point on screen instead.
    readout(s, xv, mx, my) {
      const g = this.g, n = s.ax.length;
      if (!n) return null;
      if (s.mono && s.style !== 'points') {
        const tol = 4 / g.sx;
        if (xv < s.ax[0] - tol || xv > s.ax[n - 1] + tol) return null;
        const k = lowerBound(s.ax, xv);
        if (k < n && s.ax[k] === xv) return { x: xv, y: s.ay[k] };
        if (k === 0) return { x: s.ax[0], y: s.ay[0] };
        if (k >= n) return { x: s.ax[n - 1], y: s.ay[n - 1] };
        const y0 = s.ay[k - 1], y1 = s.ay[k];
        if (s.style === 'step') return { x: xv, y: y0 };
        const f = (xv - s.ax[k - 1]) / (s.ax[k] - s.ax[k - 1]);
        return { x: xv, y: y0 + f * (y1 - y0) };  // NaN if either side is a gap
      }
      let best = -1, bd = 14 * 14;  // within 14 px
      for (let k = 0; k < n; k++) {
        if (!isFinite(s.ay[k])) continue;
        const dx = g.X(s.ax[k]) - mx, dy = g.Y(s.ay[k]) - my, d = dx * dx + dy * dy;
        if (d < bd) { bd = d; best = k; }
      }
      return best < 0 ? null : { x: s.ax[best], y: s.ay[best], snapped: true };
    }

    hover(mx, my, e) {
      const g = this.g;
      if (!this.inPlot(mx, my)) {
        for (const p of this.linked()) { p.cursor = null; p.drawOverlay(); }
        hideTip();
        return;
      }
      const xv = g.x0 + (mx - g.l) / g.sx;
      for (const p of this.linked()) { p.cursor = xv; p.marks = null; if (p !== this) p.drawOverlay(); }
      const xr = this.xLog ? Math.pow(10, xv) : xv;
      const rows = [];
      this.marks = [];
      let xShown = xr;
      for (const s of this.series) {
        if (s.hidden) continue;
        const r = this.readout(s, xv, mx, my);
        if (!r) continue;
        const yr = !isFinite(r.y) ? null : this.yLog ? Math.pow(10, r.y) : r.y;
        if (r.snapped) xShown = this.xLog ? Math.pow(10, r.x) : r.x;
        if (isFinite(r.y)) this.marks.push([r.x, r.y, s.color]);
        const kind = s.style === 'points' ? 'dot' : s.dashed ? 'dashed' : '';
        rows.push(tipSwatch(s.color, kind) + esc(s.name) + '<span class="v">' + fmtVal(yr) + '</span>');
      }
      for (const b of this.bands) {
        if (b.label && xv >= b.a && xv <= b.b) rows.push('<span class="band">\u25A0 ' + esc(b.label) + '</span>');
      }
      this.drawOverlay();
      const xName = this.spec.xLabel || 'x';
      // The cursor's x is only known to a pixel: show the digits a pixel resolves, no more.
      const xText = xShown !== xr || this.xLog ? fmtVal(xShown) : fmtTick(xr, Math.pow(10, Math.floor(Math.log10(1 / g.sx))));
      showTip('<div class="hd">' + esc(xName) + ' = ' + xText + '</div>' +
        (rows.length ? rows.join('<br>') : '<span class="hd">no value here</span>'), e.clientX, e.clientY);
    }

    drawOverlay() {
      const ctx = this.octx, g = this.g;
      if (!g) return;
      ctx.clearRect(0, 0, this.cssW, this.height);
      if (this.sel) {
        const [a, b] = this.sel;
        ctx.fillStyle = C.select;
        ctx.fillRect(Math.min(a, b), g.t, Math.abs(b - a), g.h);
        ctx.strokeStyle = C.selectEdge;
        ctx.lineWidth = 1;
        ctx.strokeRect(this.crisp(Math.min(a, b)), this.crisp(g.t), Math.round(Math.abs(b - a)), Math.round(g.h));
      }
      if (this.cursor !== null && this.cursor >= g.x0 && this.cursor <= g.x1) {
        const px = this.crisp(g.X(this.cursor));
        ctx.strokeStyle = C.cursor;
        ctx.lineWidth = 1;
        ctx.setLineDash([3, 3]);
        ctx.beginPath();
        ctx.moveTo(px, g.t);
        ctx.lineTo(px, g.t + g.h);
        ctx.stroke();
        ctx.setLineDash([]);
        for (const [x, y, color] of this.marks || []) {
          ctx.beginPath();
          ctx.arc(g.X(x), g.Y(y), 3.5, 0, 2 * Math.PI);
          ctx.fillStyle = '#fff';
          ctx.fill();
          ctx.lineWidth = 2;
          ctx.strokeStyle = color;
          ctx.stroke();
        }
      }
    }
  }

  // ---------- grouped bar chart ----------

  class BarChart extends Chart {
    constructor(fig, spec) {
      super(fig, spec);
      this.cats = spec.categories || [];
      this.groups = (spec.groups || []).map((gr, i) => ({ name: gr.name || 'group ' + (i + 1),
        color: PALETTE[i % PALETTE.length], values: gr.values.map(v => (v === null ? NaN : v)), hidden: false }));
      if (this.groups.length > 1 || (this.groups.length === 1 && spec.groups[0].name)) {
        for (const gr of this.groups) {
          gr.button = this.legendItem(gr.name, gr.color, 'box', b => {
            gr.hidden = !gr.hidden;
            b.classList.toggle('off', gr.hidden);
            this.schedule();
          }, () => {
            const alone = this.groups.every(o => o === gr || o.hidden);
            for (const o of this.groups) { o.hidden = alone ? false : o !== gr; o.button.classList.toggle('off', o.hidden); }
            this.schedule();
          });
        }
      }
      this.hot = -1;
      this.overlay.style.cursor = 'default';
      this.overlay.addEventListener('pointermove', e => this.hover(e));
      this.overlay.addEventListener('pointerleave', () => { this.hot = -1; this.drawOverlay(); hideTip(); });
    }

    render(countInk) {
      // Category labels: horizontal if they fit their slot, else slanted, and then the canvas
      // grows by their depth so the bars keep the height asked for.
      const ctx = this.ctx;
      ctx.font = FONT;
      const labels = this.cats.map(c => (c.length > 28 ? c.slice(0, 27) + '\u2026' : c));
      let widest = 0;
      for (const s of labels) widest = Math.max(widest, ctx.measureText(s).width);
      const guessW = (this.wrap.clientWidth || 600) - 70 - 16;
      const slant = this.cats.length > 0 && widest + 8 > guessW / this.cats.length;
      const b = slant ? Math.min(130, Math.ceil(widest * Math.sin(Math.PI / 5)) + 26) : 26;
      this.height = (this.spec.height || 260) + b - 26;
      this.wrap.style.height = this.height + 'px';
      if (!this.size()) return;
      const W = this.cssW, H = this.height;
      ctx.clearRect(0, 0, W, H);
      ctx.fillStyle = C.bg;
      ctx.fillRect(0, 0, W, H);
      const shown = this.groups.filter(gr => !gr.hidden);
      let lo = 0, hi = 0, any = false;
      for (const gr of shown) for (const v of gr.values) if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); any = true; }
      if (hi === lo) hi = lo + 1;
      const pad = (hi - lo) * 0.08;
      if (hi > 0) hi += pad;
      if (lo < 0) lo -= pad;

      const t = 10;
      const h = Math.max(20, H - t - b);
      const yt = ticks(lo, hi, false, Math.max(2, Math.floor(h / 42)));
      const majors = yt.filter(v => v.major);
      if (majors.length > 1) {  // extend to whole ticks so the top bar does not touch the frame
        const step = majors[1].v - majors[0].v;
        if (hi > 0) hi = Math.max(hi, Math.ceil(hi / step - 1e-9) * step);
        if (lo < 0) lo = Math.min(lo, Math.floor(lo / step + 1e-9) * step);
      }
      const yt2 = ticks(lo, hi, false, Math.max(2, Math.floor(h / 42)));
      const l = this.leftMargin(yt2, this.spec.yLabel);
      const w = Math.max(20, W - l - 16);
      const g = { l, t, w, h, y0: lo, y1: hi, sy: h / (hi - lo) };
      g.Y = v => g.t + g.h - (v - g.y0) * g.sy;
      g.slot = this.cats.length ? w / this.cats.length : w;
      this.g = g;

      this.drawGrid(g, [], yt2);
      this.inked(g, countInk, () => {
        const inner = g.slot * 0.78, bw = shown.length ? inner / shown.length : 0;
        const y0 = g.Y(0);
        ctx.font = FONT_SMALL;
        const room = bw >= 30 && this.cats.length * shown.length <= 48;
        shown.forEach((gr, j) => {
          ctx.fillStyle = gr.color;
          gr.values.forEach((v, i) => {
            if (!isFinite(v)) return;
            const x = l + i * g.slot + (g.slot - inner) / 2 + j * bw;
            const y = g.Y(v);
            ctx.fillRect(x + 0.5, Math.min(y, y0), Math.max(1, bw - 1), Math.max(1, Math.abs(y0 - y)));
          });
        });
        if (room) {  // value labels above the bars when they have room
          shown.forEach((gr, j) => gr.values.forEach((v, i) => {
            if (!isFinite(v)) return;
            const x = l + i * g.slot + (g.slot - inner) / 2 + (j + 0.5) * bw;
            const y = g.Y(v);
            this.drawText(ctx, fmtVal(Number(v.toPrecision(3))), x, v >= 0 ? y - 2 : y + 2, 'center', v >= 0 ? 'bottom' : 'top', FONT_SMALL, C.text);
          }));
        }
      });
      ctx.strokeStyle = C.tick;
      ctx.lineWidth = 1;
      ctx.beginPath();
      const zy = this.crisp(g.Y(0));
      ctx.moveTo(l, zy);
      ctx.lineTo(l + w, zy);
      ctx.stroke();
      this.drawFrame(g);
      this.drawYAxis(g, yt2, this.spec.yLabel);
      labels.forEach((s, i) => {
        const cx = l + (i + 0.5) * g.slot;
        if (!slant) { this.drawText(ctx, s, cx, t + h + 6, 'center', 'top'); return; }
        ctx.font = FONT;  // slanted labels run left: shorten those that would leave the canvas
        const room = (cx - 2) / Math.cos(Math.PI / 5);
        let n = s.length;
        while (n > 1 && ctx.measureText(s.slice(0, n) + (n < s.length ? '\u2026' : '')).width > room) n--;
        if (n < s.length) s = s.slice(0, n) + '\u2026';
        ctx.save();
        ctx.translate(cx, t + h + 6);
        ctx.rotate(-Math.PI / 5);
        this.drawText(ctx, s, 0, 0, 'right', 'top');
        ctx.restore();
      });
      if (!any) this.noData(g);
      this.canvas.setAttribute('data-rendered', '1');
      this.drawOverlay();
    }

    hover(e) {
      const g = this.g;
      if (!g) return;
      const r = this.overlay.getBoundingClientRect();
      const mx = e.clientX - r.left, my = e.clientY - r.top;
      const i = Math.floor((mx - g.l) / g.slot);
      if (mx < g.l || i < 0 || i >= this.cats.length || my > g.t + g.h + 40) {
        this.hot = -1; this.drawOverlay(); hideTip(); return;
      }
      this.hot = i;
      this.drawOverlay();
      const rows = this.groups.filter(gr => !gr.hidden).map(gr =>
        tipSwatch(gr.color, 'box') + esc(gr.name) + '<span class="v">' + fmtVal(gr.values[i]) + '</span>');
      showTip('<div class="hd">' + esc(this.cats[i]) + '</div>' + rows.join('<br>'), e.clientX, e.clientY);
    }

    drawOverlay() {
      const ctx = this.octx, g = this.g;
      if (!g) return;
      ctx.clearRect(0, 0, this.cssW, this.height);
      if (this.hot >= 0) {
        ctx.fillStyle = 'rgba(31,111,235,0.07)';
        ctx.fillRect(g.l + this.hot * g.slot, g.t, g.slot, g.h);
      }
    }
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

  function publish() {
    document.body.setAttribute('data-plots', String(stats.plots));
    document.body.setAttribute('data-plot-errors', String(stats.errors));
    if (stats.first) document.body.setAttribute('data-plot-error-first', stats.first);
  }

  function renderAll(countInk) { for (const c of all) c.safeRender(countInk); }

  // For tests and the curious: the charts, in page order (read-only use intended).
  window.hilReport = { charts: all, stats };

  function start() {
    tip = document.querySelector('.hil-tip');
    for (const fig of document.querySelectorAll('figure.hil-fig')) {
      try {
        const data = fig.querySelector('script.hil-data');
        const spec = JSON.parse(data.textContent);
        const chart = spec.kind === 'bars' ? new BarChart(fig, spec) : new Plot(fig, spec);
        all.push(chart);
        chart.render(true);
        stats.plots++;
      } catch (e) {
        fail(fig, e);
      }
    }
    document.querySelectorAll('table.hil-table').forEach(sortable);
    publish();
    // Re-render on width changes (window resize, columns reflowing), not on every frame.
    if (window.ResizeObserver) {
      const ro = new ResizeObserver(entries => {
        for (const en of entries) {
          const c = en.target.hilChart;
          if (c && Math.floor(en.target.clientWidth) !== c.cssW) c.safeRender(true);
        }
      });
      for (const c of all) { c.wrap.hilChart = c; ro.observe(c.wrap); }
    } else {
      window.addEventListener('resize', () => renderAll(true));
    }
    window.addEventListener('beforeprint', () => { printDpr = Math.max(2, window.devicePixelRatio || 1); renderAll(false); });
    window.addEventListener('afterprint', () => { printDpr = 0; renderAll(false); });
  }

  window.addEventListener('error', e => { stats.errors++; if (!stats.first) stats.first = String(e.message); publish(); });
  if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
