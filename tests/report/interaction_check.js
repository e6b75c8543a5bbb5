// Appended to a report by browser_test.cpp: drives the plots with synthetic pointer, wheel and
// click events and writes the outcome to <body data-interaction="ok"> (or the failures).
// Uses window.hilReport.charts, which report.js exposes in page order.
document.addEventListener('DOMContentLoaded', async () => {
  const failures = [];
  // Zooms re-render on the next frame; geometry for the next gesture needs that render. A timer,
  // not requestAnimationFrame: headless Chromium's virtual time runs timers but few frames.
  const frame = () => new Promise(resolve => setTimeout(resolve, 150));
  const check = (cond, what) => { if (!cond) failures.push(what); };
  try {
    const charts = window.hilReport.charts;
    const plots = charts.filter(c => c.series);
    const grouped = plots.filter(p => p.group === 'campaign');
    const a = grouped[0], b = grouped[1];
    const at = (p, fx, fy) => {  // client coordinates of a fraction of p's plot area
      const r = p.overlay.getBoundingClientRect();
      return { clientX: r.left + p.g.l + fx * p.g.w, clientY: r.top + p.g.t + fy * p.g.h };
    };
    const fire = (el, type, pos, extra) => {
      const init = Object.assign({ bubbles: true, cancelable: true, pointerId: 1, button: 0, isPrimary: true }, pos, extra);
      const ev = type.startsWith('pointer') ? new PointerEvent(type, init)
        : type === 'wheel' ? new WheelEvent(type, init) : new MouseEvent(type, init);
      el.dispatchEvent(ev);
    };
    const span = p => p.xRange()[1] - p.xRange()[0];
    const full = a.fullX[1] - a.fullX[0];

    // Drag a box over the middle fifth: zooms x, and the linked plot follows.
    fire(a.overlay, 'pointerdown', at(a, 0.4, 0.5));
    fire(a.overlay, 'pointermove', at(a, 0.5, 0.5));
    fire(a.overlay, 'pointermove', at(a, 0.6, 0.5));
    fire(a.overlay, 'pointerup', at(a, 0.6, 0.5));
    check(a.view && Math.abs(span(a) - 0.2 * full) < 0.01 * full, 'box zoom sets x range: ' + JSON.stringify(a.view));
    check(b.view && b.view[0] === a.view[0] && b.view[1] === a.view[1], 'linked plot follows the zoom');

    await frame();
    check(a.resetButton.style.visibility === 'visible', 'reset button shows when zoomed');
    // Shift+drag pans by the dragged distance.
    const before = a.view.slice();
    fire(a.overlay, 'pointerdown', at(a, 0.5, 0.5), { shiftKey: true });
    fire(a.overlay, 'pointermove', at(a, 0.25, 0.5), { shiftKey: true });
    fire(a.overlay, 'pointerup', at(a, 0.25, 0.5), { shiftKey: true });
    const moved = a.view[0] - before[0];
    check(Math.abs(moved - 0.25 * (before[1] - before[0])) < 1e-6 * full, 'shift+drag pans: moved ' + moved);
    check(b.view[0] === a.view[0], 'linked plot follows the pan');

    await frame();
    // Double-click resets both.
    fire(a.overlay, 'dblclick', at(a, 0.5, 0.5));
    check(a.view === null && b.view === null, 'double-click resets the group');

    await frame();
    // Wheel: ignored until the plot is active, unless ctrl is held.
    a.active = false;
    fire(a.overlay, 'wheel', Object.assign(at(a, 0.5, 0.5), { deltaY: -200 }));
    check(a.view === null, 'plain wheel over an inactive plot scrolls the page instead');
    fire(a.overlay, 'wheel', Object.assign(at(a, 0.5, 0.5), { deltaY: -200, ctrlKey: true }));
    check(a.view && span(a) < 0.9 * full, 'ctrl+wheel zooms in');
    fire(a.overlay, 'dblclick', at(a, 0.5, 0.5));
    await frame();

    // Hover: a tooltip with the series values, and a cursor in the linked plot.
    fire(a.overlay, 'pointermove', at(a, 0.3, 0.5));
    const tip = document.querySelector('.hil-tip');
    check(!tip.hidden && tip.textContent.includes('measured') && tip.textContent.includes('time [s]'),
      'hover shows a read-out: ' + tip.textContent);
    check(b.cursor !== null && Math.abs(b.cursor - a.cursor) < 1e-9, 'hover cursor is linked');
    fire(a.overlay, 'pointerleave', at(a, 1.2, 0.5));
    check(tip.hidden && b.cursor === null, 'leaving hides the read-out');

    await frame();
    // Legend: click hides a series, double-click shows it alone.
    const s0 = a.series[0], s1 = a.series[1];
    s0.button.click();
    check(s0.hidden && s0.button.classList.contains('off'), 'legend click hides a series');
    s0.button.click();
    check(!s0.hidden, 'second click shows it again');
    s1.button.dispatchEvent(new MouseEvent('dblclick', { bubbles: true }));
    check(s0.hidden && !s1.hidden, 'legend double-click isolates a series');

    await frame();
    // Bars: hovering a category reads out its values.
    const bars = charts.find(c => c.cats);
    if (bars) {
      const r = bars.overlay.getBoundingClientRect();
      fire(bars.overlay, 'pointermove', { clientX: r.left + bars.g.l + 0.5 * bars.g.slot, clientY: r.top + bars.g.t + 10 });
      check(!tip.hidden && tip.textContent.includes(bars.cats[0]), 'bar hover shows the category');
    }

    await frame();
    // Log axes: y ticks are decades.
    const logPlot = plots.find(p => p.yLog);
    if (logPlot) check(logPlot.g.y1 - logPlot.g.y0 > 2, 'log plot spans decades');

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
  await frame();  // renders scheduled by the last events, so their errors are counted too
  document.body.setAttribute('data-interaction', failures.length ? failures.join(' | ') : 'ok');
});
