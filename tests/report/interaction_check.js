// Appended to a report by browser_test.cpp: drives the plots (Dygraphs) with synthetic mouse,
// wheel and click events, as a user's would arrive, and writes the outcome to
// <body data-interaction="ok"> (or the failures). Uses window.hilReport.charts (page order) and
// the Dygraph API (xAxisRange, isZoomed, getSelection, visibility) to read back the state.
document.addEventListener('DOMContentLoaded', async () => {
  const failures = [];
  // Gives scheduled work (resize observers, timers) a turn between gestures; a timer, not
  // requestAnimationFrame: headless Chromium's virtual time runs timers but few frames.
  const frame = () => new Promise(resolve => setTimeout(resolve, 150));
  const check = (cond, what) => { if (!cond) failures.push(what); };
  try {
    const charts = window.hilReport.charts;
    const plots = charts.filter(c => c.kind !== 'bars');
    const grouped = plots.filter(p => p.group === 'campaign');
    const a = grouped[0], b = grouped[1];
    // Dygraphs listens on its top canvas (the interaction layer above the drawn plot).
    const target = p => p.div.querySelector('canvas:not(.hil-plot)');
    const at = (p, fx, fy) => {  // client coordinates of a fraction of p's plot area
      const r = target(p).getBoundingClientRect(), area = p.graph.getArea();
      return { clientX: r.left + area.x + fx * area.w, clientY: r.top + area.y + fy * area.h };
    };
    const fire = (el, type, pos, extra) => {
      const init = Object.assign({ bubbles: true, cancelable: true, button: 0, view: window }, pos, extra);
      el.dispatchEvent(type === 'wheel' ? new WheelEvent(type, init) : new MouseEvent(type, init));
    };
    const drag = (p, fx0, fx1, extra) => {
      const el = target(p);
      fire(el, 'mousedown', at(p, fx0, 0.5), extra);
      fire(el, 'mousemove', at(p, (fx0 + fx1) / 2, 0.5), extra);
      fire(el, 'mousemove', at(p, fx1, 0.5), extra);
      fire(el, 'mouseup', at(p, fx1, 0.5), extra);
    };
    // A double-click as a mouse makes it: two presses, then dblclick (dygraphs ignores a dblclick
    // that ends a drag, and a press clears that).
    const dblclick = (p, fx) => {
      const el = target(p), pos = at(p, fx, 0.5);
      for (const type of ['mousedown', 'mouseup', 'click', 'mousedown', 'mouseup', 'click', 'dblclick']) fire(el, type, pos);
    };
    const range = p => p.graph.xAxisRange();
    const span = p => range(p)[1] - range(p)[0];
    const full = span(a);
    const same = (r, s) => Math.abs(r[0] - s[0]) < 1e-9 * Math.abs(s[1] - s[0]) && Math.abs(r[1] - s[1]) < 1e-9 * Math.abs(s[1] - s[0]);

    // Drag across the middle fifth: zooms x to that span, and the linked plot follows.
    drag(a, 0.4, 0.6);
    check(a.graph.isZoomed('x') && Math.abs(span(a) - 0.2 * full) < 0.01 * full, 'box zoom sets x range: ' + JSON.stringify(range(a)));
    check(b.graph.isZoomed('x') && same(range(b), range(a)), 'linked plot follows the zoom: ' + JSON.stringify(range(b)));

    await frame();
    check(a.resetButton.style.visibility === 'visible', 'reset button shows when zoomed');
    // Shift+drag pans by the dragged distance.
    const before = range(a);
    drag(a, 0.5, 0.25, { shiftKey: true });
    const moved = range(a)[0] - before[0];
    check(Math.abs(moved - 0.25 * (before[1] - before[0])) < 0.01 * (before[1] - before[0]), 'shift+drag pans: moved ' + moved);
    check(Math.abs(span(a) - (before[1] - before[0])) < 1e-6 * full, 'panning keeps the span');
    check(same(range(b), range(a)), 'linked plot follows the pan');

    await frame();
    // Double-click resets both; so does the reset button.
    dblclick(a, 0.5);
    check(!a.graph.isZoomed('x') && !b.graph.isZoomed('x'), 'double-click resets the group');
    check(a.resetButton.style.visibility === 'hidden', 'reset button hides at the full view');
    drag(a, 0.2, 0.7);
    a.resetButton.click();
    check(!a.graph.isZoomed('x') && !b.graph.isZoomed('x'), 'the reset button resets the group');

    await frame();
    // Wheel: ignored until the plot is active (clicked), unless ctrl is held.
    a.active = false;
    fire(target(a), 'wheel', Object.assign(at(a, 0.5, 0.5), { deltaY: -200 }));
    check(!a.graph.isZoomed('x'), 'plain wheel over an inactive plot scrolls the page instead');
    fire(target(a), 'wheel', Object.assign(at(a, 0.5, 0.5), { deltaY: -200, ctrlKey: true }));
    check(a.graph.isZoomed('x') && span(a) < 0.9 * full, 'ctrl+wheel zooms in');
    check(same(range(b), range(a)), 'linked plot follows the wheel zoom');
    dblclick(a, 0.5);
    await frame();

    // Hover: a read-out with the x axis' name and the series values, and the cursor in the linked plot.
    fire(target(a), 'mousemove', at(a, 0.3, 0.5));
    const tip = a.fig.querySelector('.dygraph-legend');
    check(tip && tip.style.display !== 'none' && tip.textContent.includes('measured') && tip.textContent.includes('time [s]'),
      'hover shows a read-out: ' + (tip && tip.textContent));
    // Every series reads its drawn curve at the cursor (lines interpolate, steps hold), also where
    // its samples fall between the rows of another series.
    check(tip && !tip.textContent.includes('\u2014'), 'every series has a value at the cursor: ' + (tip && tip.textContent));
    const xa = a.graph.getSelection() >= 0 ? a.graph.getValue(a.graph.getSelection(), 0) : NaN;
    const xb = b.graph.getSelection() >= 0 ? b.graph.getValue(b.graph.getSelection(), 0) : NaN;
    check(Math.abs(xa - (range(a)[0] + 0.3 * full)) < 0.01 * full, 'hover selects the x under the cursor: ' + xa + ' in ' + range(a));
    check(Math.abs(xb - xa) < 0.01 * full, 'hover cursor is linked: ' + xb + ' vs ' + xa);
    fire(target(a), 'mouseout', at(a, 1.2, 0.5));
    check(tip.style.display === 'none' && b.graph.getSelection() === -1, 'leaving hides the read-out and the linked cursor');

    await frame();
    // Legend: click hides a series, double-click shows it alone.
    const s0 = a.items[0], s1 = a.items[1];
    s0.button.click();
    check(s0.hidden && s0.button.classList.contains('off') && !a.graph.visibility()[0], 'legend click hides a series');
    s0.button.click();
    check(!s0.hidden && a.graph.visibility()[0], 'second click shows it again');
    s1.button.dispatchEvent(new MouseEvent('dblclick', { bubbles: true }));
    check(s0.hidden && !s1.hidden && !a.graph.visibility()[0] && a.graph.visibility()[1], 'legend double-click isolates a series');

    await frame();
    // Bars: hovering a category reads out its values; dragging does not zoom them.
    const bars = charts.find(c => c.kind === 'bars');
    if (bars) {
      fire(target(bars), 'mousemove', at(bars, 0.5 / bars.cats.length, 0.5));
      const btip = bars.fig.querySelector('.dygraph-legend');
      check(btip && btip.style.display !== 'none' && btip.textContent.includes(bars.cats[0]), 'bar hover shows the category: ' +
        (btip && btip.textContent));
      const shown = range(bars);
      drag(bars, 0.1, 0.6);
      check(same(range(bars), [-0.5, bars.cats.length - 0.5]) && same(range(bars), shown), 'bars do not zoom: ' + range(bars));
    } else {
      failures.push('no bar chart on the page');
    }

    await frame();
    // Log axes: y spans decades.
    const logPlot = plots.find(p => p.spec.yLog);
    if (logPlot) {
      const [y0, y1] = logPlot.graph.yAxisRange();
      check(logPlot.graph.getOptionForAxis('logscale', 'y') && Math.log10(y1 / y0) > 2, 'log plot spans decades: ' + [y0, y1]);
    }

    await frame();
    // Tables sort by a clicked numeric column.
    const table = [...document.querySelectorAll('table.hil-table')].find(t => t.rows.length > 3);
    if (table) {
      const th = table.tHead.rows[0].cells[2];
      th.click();
      th.click();  // descending
      const col = [...table.tBodies[0].rows].map(r => parseFloat(r.cells[2].textContent));
      check(col.every((v, i) => i === 0 || col[i - 1] >= v), 'table sorts descending: ' + col);
    }
  } catch (e) {
    failures.push('exception: ' + e.message);
  }
  await frame();  // draws scheduled by the last events, so their errors are counted too
  document.body.setAttribute('data-interaction', failures.length ? failures.join(' | ') : 'ok');
});
