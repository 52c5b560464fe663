// gelgrip dashboard: axis ticks and their labels, shared by every chart of the page.
// The rule is the one `gelgrip plot` uses (src/plot/axis.rs): "nice" steps (1, 2, 2.5 or
// 5 × 10^k), as many decimals as the step needs (so neighbouring labels differ), and the
// unit on every label ("0.25 mm³", "-30 s").
"use strict";

(function () {
  // Magnitudes past this are clamped, so a span is always finite.
  const LIMIT = 1e300;
  // The narrowest span, absolute (toFixed takes at most 100 decimals) and relative to the
  // values (finer steps than this are lost in rounding: labels would repeat).
  const LEAST_SPAN = 1e-90;
  const LEAST_RELATIVE = 1e-9;

  // [lo, hi]: finite, lo < hi, wide enough to label.
  function range(lo, hi) {
    const a = Number.isFinite(lo);
    const b = Number.isFinite(hi);
    if (a && !b) hi = lo;
    else if (b && !a) lo = hi;
    else if (!a && !b) lo = hi = 0;
    lo = Math.min(Math.max(lo, -LIMIT), LIMIT);
    hi = Math.min(Math.max(hi, -LIMIT), LIMIT);
    if (lo > hi) [lo, hi] = [hi, lo];
    const mid = lo / 2 + hi / 2;
    if (hi - lo >= Math.max(Math.abs(mid) * LEAST_RELATIVE, LEAST_SPAN)) return [lo, hi];
    if (mid === 0) return [0, 1];
    const half = Math.max(Math.abs(mid) * 0.1, LEAST_SPAN);
    return [mid - half, mid + half];
  }

  // The nice step that puts at most `maxTicks` ticks in [lo, hi] (a valid range).
  function niceStep(lo, hi, maxTicks) {
    const raw = (hi - lo) / (maxTicks - 1);
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 2.5, 5]) {
      if (m * p >= raw * (1 - 1e-9)) return m * p;
    }
    return 10 * p;
  }

  // Decimals that tell multiples of `step` apart: 0.25 → 2, 2.5 → 1, 0.001 → 3, 20 → 0.
  function decimals(step) {
    const e = Math.floor(Math.log10(step) + 1e-9);
    const m = step / Math.pow(10, e);
    const d = -e + (Math.abs(m - 2.5) < 1e-6 ? 1 : 0);
    return Math.min(Math.max(d, 0), 100);
  }

  // Ticks of [lo, hi] (at most `maxTicks`, at least 3 asked for) as [{value, label}], the
  // label a number with the step's decimals, a space and `unit`. Any input (lo == hi, NaN,
  // ±Infinity) gives finite values and labels without NaN.
  function axisTicks(lo, hi, unit, maxTicks) {
    const n = Number.isFinite(maxTicks) ? Math.max(3, Math.floor(maxTicks)) : 5;
    [lo, hi] = range(lo, hi);
    const step = niceStep(lo, hi, n);
    const d = decimals(step);
    const suffix = unit ? " " + unit : "";
    const ticks = [];
    for (let k = Math.ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9 && ticks.length < n; k++) {
      const value = k * step + 0; // + 0: no -0
      let text = value.toFixed(d);
      if (/^-0\.?0*$/.test(text)) text = text.slice(1);
      ticks.push({ value, label: text + suffix });
    }
    return ticks;
  }

  window.gelgripAxis = { axisTicks };
})();
