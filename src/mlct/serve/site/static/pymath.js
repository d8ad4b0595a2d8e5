// Python's and numpy's rounding and order statistics, as the page's ports of mlct's Python
// need them to give the same numbers (model.js, keepgoing.js, bvh.js).
"use strict";

// Python's round(): halves to even (frames from seconds as mlct.generate computes them).
export function roundHalfEven(x) {
  const r = Math.round(x);
  return Math.abs(x % 1) === 0.5 && r % 2 !== 0 ? r - 1 : r;
}

// numpy.percentile's default: linear interpolation between the closest ranks.
export function percentile(values, q) {
  const sorted = Float64Array.from(values).sort();
  const at = (q / 100) * (sorted.length - 1);
  const low = Math.floor(at);
  const high = Math.min(low + 1, sorted.length - 1);
  return sorted[low] + (at - low) * (sorted[high] - sorted[low]);
}

export const median = (values) => percentile(values, 50);
