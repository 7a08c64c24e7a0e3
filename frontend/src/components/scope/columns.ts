/**
 * How a decimated trace is drawn: one vertical stroke per pixel column, from the column's
 * minimum to its maximum (decimate.ts keeps both, in the order they occurred), stretched to
 * reach the previous column's last value so the trace stays one connected line.
 *
 * Why not a polyline through the min and max of every column (uPlot's default path): with 32
 * traces of ~1,000 columns that is 64,000 diagonal, antialiased segments that reverse at every
 * column, and software rasterisation of them (Chromium without a GPU, at the compositor's
 * commit on the page's main thread) took about 55 ms per frame on the project's machine;
 * the same columns as vertical strokes take about 14 ms and cover the same pixels (a column's
 * samples lie between its min and max). Measured by bench/bench_scope_ui.py.
 *
 * Pure: pixel positions in, segments out (the plot turns them into a Path2D).
 */

/**
 * Segments (x0, y0, x1, y1 quadruples, canvas pixels) of one trace of decimated data.
 *
 * `px` and `py` give the pixel position of each slot of the aligned data (NaN in `py`: no
 * value of this trace there). Slots [0, off) are the samples just left of the window, then two
 * slots per column for `count` columns (first and second value of the column, in time order),
 * then the samples right of the window. A column's stroke is drawn at the middle of its two
 * slots, rounded to a whole pixel.
 */
export function columnSegments(px: ArrayLike<number>, py: ArrayLike<number>, off: number, count: number): Float64Array {
  const len = Math.min(px.length, py.length);
  // At most a joining segment and a stroke per column, and the joins to either edge.
  const out = new Float64Array(8 * count + 8);
  let n = 0;
  const push = (x0: number, y0: number, x1: number, y1: number) => {
    out[n++] = x0;
    out[n++] = y0;
    out[n++] = x1;
    out[n++] = y1;
  };
  let prevX = NaN;
  let prevY = NaN;
  // The last sample left of the window, if this trace has one.
  for (let i = off - 1; i >= 0; i--) {
    const y = py[i] as number;
    if (!Number.isNaN(y)) {
      prevX = px[i] as number;
      prevY = y;
      break;
    }
  }
  for (let c = 0; c < count; c++) {
    const i = off + 2 * c;
    const a = py[i] as number;
    const b = i + 1 < len ? (py[i + 1] as number) : NaN;
    if (Number.isNaN(a) && Number.isNaN(b)) continue;
    const first = Number.isNaN(a) ? b : a;
    const last = Number.isNaN(b) ? a : b;
    const x = Math.round(((px[i] as number) + (px[i + 1] ?? (px[i] as number))) / 2);
    let top = Math.min(first, last);
    let bottom = Math.max(first, last);
    if (!Number.isNaN(prevY)) {
      if (x - prevX <= 1.5) {
        // The neighbouring column: its last value joins this column's stroke.
        top = Math.min(top, prevY);
        bottom = Math.max(bottom, prevY);
      } else push(prevX, prevY, x, first);
    }
    // A stroke of no length draws nothing: a flat column still shows one pixel.
    top = Math.floor(top);
    bottom = Math.max(Math.ceil(bottom), top + 1);
    push(x, top, x, bottom);
    prevX = x;
    prevY = last;
  }
  // The first sample right of the window.
  for (let i = off + 2 * count; i < len; i++) {
    const y = py[i] as number;
    if (!Number.isNaN(y)) {
      if (!Number.isNaN(prevY)) push(prevX, prevY, px[i] as number, y);
      break;
    }
  }
  return out.subarray(0, n);
}
