// Small 2D line plots drawn on a canvas.

export class LinePlot {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{color?: string, xLabel?: string, maxPoints?: number}} [opts] maxPoints: the most values kept (0: all)
   */
  constructor(canvas, { color = '#4c9aff', xLabel = '', maxPoints = 0 } = {}) {
    this.canvas = canvas;
    this.color = color;
    this.xLabel = xLabel;
    this.maxPoints = maxPoints;
    /** @type {number[]} */
    this.values = [];
    new ResizeObserver(() => this.draw()).observe(canvas);
  }

  /** @param {Iterable<number>|ArrayLike<number>} values the values to draw (those not finite are left out) */
  set(values) {
    this.values = Array.from(values).filter((v) => Number.isFinite(v));
    this.draw();
  }

  /**
   * Append a value; `draw` false leaves the drawing to a later draw().
   * @param {number} value
   * @param {boolean} [draw]
   */
  push(value, draw = true) {
    if (!Number.isFinite(value)) return;
    this.values.push(value);
    if (this.maxPoints && this.values.length > this.maxPoints) this.values.splice(0, this.values.length - this.maxPoints);
    if (draw) this.draw();
  }

  clear() {
    this.values = [];
    this.draw();
  }

  draw() {
    const c = this.canvas;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(c.clientWidth * dpr));
    const h = Math.max(1, Math.round(c.clientHeight * dpr));
    if (c.width !== w || c.height !== h) {
      c.width = w;
      c.height = h;
    }
    const ctx = /** @type {CanvasRenderingContext2D} */ (c.getContext('2d')); // a canvas has a 2D context
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const W = c.clientWidth;
    const H = c.clientHeight;
    ctx.clearRect(0, 0, W, H);
    const padL = 50;
    const padR = 8;
    const padT = 8;
    const padB = 16;
    ctx.font = '10px system-ui, sans-serif';
    ctx.strokeStyle = '#333a44';
    ctx.lineWidth = 1;
    for (let k = 0; k <= 2; k++) {
      const y = Math.round(padT + ((H - padT - padB) * k) / 2) + 0.5;
      ctx.beginPath();
      ctx.moveTo(padL, y);
      ctx.lineTo(W - padR, y);
      ctx.stroke();
    }
    const vals = this.values;
    ctx.fillStyle = '#8b94a1';
    if (!vals.length) {
      ctx.textAlign = 'center';
      ctx.fillText('no data yet', (padL + W - padR) / 2, H / 2 + 3);
      return;
    }
    let lo = Math.min(...vals);
    let hi = Math.max(...vals);
    if (hi - lo < 1e-12 * Math.max(1, Math.abs(hi))) {
      hi += Math.abs(hi) * 0.05 + 1e-12;
      lo -= Math.abs(lo) * 0.05 + 1e-12;
    }
    const sx = (/** @type {number} */ i) => padL + (vals.length === 1 ? 0.5 : i / (vals.length - 1)) * (W - padL - padR);
    const sy = (/** @type {number} */ v) => padT + (1 - (v - lo) / (hi - lo)) * (H - padT - padB);
    ctx.textAlign = 'right';
    ctx.fillText(fmt(hi), padL - 4, padT + 4);
    ctx.fillText(fmt(lo), padL - 4, H - padB + 3);
    ctx.textAlign = 'left';
    ctx.fillText(`${vals.length} ${this.xLabel}`, padL, H - 3);
    ctx.strokeStyle = this.color;
    ctx.lineWidth = 1.6;
    ctx.beginPath();
    vals.forEach((v, i) => (i ? ctx.lineTo(sx(i), sy(v)) : ctx.moveTo(sx(i), sy(v))));
    ctx.stroke();
    if (vals.length <= 40) {
      ctx.fillStyle = this.color;
      vals.forEach((v, i) => {
        ctx.beginPath();
        ctx.arc(sx(i), sy(v), 2, 0, Math.PI * 2);
        ctx.fill();
      });
    }
  }
}

/**
 * A number in a few characters, for a plot's axis.
 * @param {number} v
 */
export function fmt(v) {
  const a = Math.abs(v);
  if (a === 0) return '0';
  if (a >= 1e4 || a < 1e-3) return v.toExponential(1);
  return v.toPrecision(4);
}
