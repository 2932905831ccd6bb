// Distortion heat map: the server's per-vertex distortion (how far each cell is from rigid) drawn as vertex colours,
// with a legend. While it is on, every new shape asks for fresh values (one request in flight at a time).
import { byId, byIdAs, inside } from './dom.js';
import { CLIENT } from './protocol.js';

/** @typedef {import('./protocol.js').DistortionServerMessage} DistortionServerMessage */
/** @typedef {import('./protocol.js').GetDistortionClientMessage} GetDistortionClientMessage */

/**
 * Colour stops of the scale, sRGB, from rigid (0) to the top of the scale (1).
 * @type {[number, number[]][]}
 */
const STOPS = [
  [0.0, [0.19, 0.29, 0.62]],
  [0.35, [0.2, 0.65, 0.75]],
  [0.65, [0.95, 0.82, 0.25]],
  [1.0, [0.86, 0.19, 0.15]],
];

/** Least time between two requests while the shape keeps changing (a drag), so the map does not slow the solve. */
export const MIN_INTERVAL_MS = 250;

const srgbToLinear = (/** @type {number} */ c) => (c < 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);

/**
 * The sRGB colour of a scale position `t` in [0, 1].
 * @param {number} t
 * @returns {number[]} r, g, b
 */
export function heatColor(t) {
  const x = Math.max(0, Math.min(1, t));
  for (let k = 1; k < STOPS.length; k++) {
    const [t1, c1] = STOPS[k];
    if (x <= t1) {
      const [t0, c0] = STOPS[k - 1];
      const u = (x - t0) / (t1 - t0);
      return c0.map((c, j) => c + u * (c1[j] - c));
    }
  }
  return STOPS[STOPS.length - 1][1];
}

const cssGradient = () => `linear-gradient(to right, ${STOPS.map(([t, c]) => `rgb(${c.map((v) => Math.round(255 * v)).join(',')}) ${100 * t}%`).join(', ')})`;

/**
 * A compact number for the legend.
 * @param {number} x
 */
function fmt(x) {
  if (!(x > 0)) return '0';
  return x >= 0.01 ? x.toFixed(x >= 1 ? 1 : 3) : x.toExponential(1);
}

export class HeatMap {
  /**
   * @param {object} opts
   * @param {import('./viewer.js').Viewer} opts.viewer the 3D view
   * @param {(msg: GetDistortionClientMessage) => boolean} opts.send
   * @param {() => Int16Array} opts.role the per-vertex roles (anchors and handles keep their colours)
   * @param {() => void} opts.restore draw the role colours again
   * @param {HTMLElement} [opts.legend]
   * @param {HTMLInputElement} [opts.checkbox] the toggle
   */
  constructor({
    viewer, send, role, restore, legend = byId('heat-legend'), checkbox = byIdAs('heatmap', HTMLInputElement),
  }) {
    this.viewer = viewer;
    this.send = send;
    this.legend = legend;
    this.role = role;
    this.restore = restore;
    this.checkbox = checkbox;
    checkbox.addEventListener('change', () => this.setOn(checkbox.checked));
    this.on = false;
    /** @type {Float32Array|null} the distortion of each vertex, while on */
    this.values = null;
    this.high = 0;
    this.inFlight = false;
    this.stale = false;
    this.lastRequest = -Infinity;
    this.timer = 0;
    inside(this.legend, '.heat-bar').style.background = cssGradient();
  }

  /**
   * Turn the heat map on (asks for values) or off (back to the role colours).
   * @param {boolean} on
   */
  setOn(on) {
    this.on = on;
    this.checkbox.checked = on;
    this.legend.hidden = !on;
    this.values = null;
    this.viewer.setHeatShown?.(on); // drawn on the plain surface: texture view steps aside meanwhile
    if (on) this.request();
    else this.restore();
  }

  /** The shape changed: ask for fresh values when the heat map is shown. */
  shapeChanged() {
    if (this.on) this.request();
  }

  /** A new mesh: old values no longer apply. */
  meshChanged() {
    this.values = null;
    this.inFlight = false;
    this.shapeChanged();
  }

  request() {
    if (this.inFlight || this.timer) {
      this.stale = true;
      return;
    }
    const wait = this.lastRequest + MIN_INTERVAL_MS - performance.now();
    if (wait > 0) {
      this.stale = true;
      this.timer = window.setTimeout(() => {
        this.timer = 0;
        if (this.stale && this.on) this.request();
      }, wait);
      return;
    }
    this.stale = false;
    this.lastRequest = performance.now();
    /** @type {GetDistortionClientMessage} */
    const msg = { type: CLIENT.GET_DISTORTION };
    this.inFlight = this.send(msg);
  }

  /**
   * A `distortion` reply.
   * @param {DistortionServerMessage & {frame: {payload: Uint8Array}}} msg with its frame (float32 per vertex)
   */
  received(msg) {
    this.inFlight = false;
    const p = msg.frame.payload;
    const values = new Float32Array(p.buffer, p.byteOffset, p.byteLength / 4);
    if (this.on && values.length === this.viewer.nVertices) {
      this.values = Float32Array.from(values);
      this.high = msg.high > 0 ? msg.high : msg.max;
      inside(this.legend, '.heat-high').textContent = fmt(this.high);
      inside(this.legend, '.heat-max').textContent = `max ${fmt(msg.max)}`;
      this.paint();
    }
    if (this.stale && this.on) this.request();
  }

  /** The request failed: let the next shape ask again. */
  failed() {
    this.inFlight = false;
  }

  /** Draw the values over the vertex colours (anchors and handles keep theirs); nothing when off. */
  paint() {
    if (!this.on || !this.values || !this.viewer.geometry) return;
    const attr = this.viewer.geometry.attributes.color;
    const c = attr.array;
    const role = this.role();
    const scale = this.high > 0 ? 1 / this.high : 0;
    for (let i = 0, n = this.values.length; i < n; i++) {
      if (role[i] !== 0) continue;
      const rgb = heatColor(this.values[i] * scale);
      c[3 * i] = srgbToLinear(rgb[0]);
      c[3 * i + 1] = srgbToLinear(rgb[1]);
      c[3 * i + 2] = srgbToLinear(rgb[2]);
    }
    attr.needsUpdate = true;
    this.viewer.requestRender();
  }
}
