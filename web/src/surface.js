// Selection along the surface in the panel: the brush metric, growing and shrinking the current role by one ring,
// and a region of interest grown from the handles by k rings or a distance along the surface.
import { byId, byIdAs } from './dom.js';
import { buildAdjacency, geodesicDistances, kRing, ringAround } from './geodesic.js';
import { FIXED, HANDLE0 } from './selection.js';

/** How a region of interest is grown from the handles: rings of edges, or distance along the surface. */
export const ROI_GROW_MODES = ['rings', 'distance'];
/** Grow steps that Shrink can take back exactly (each keeps a copy of the selection). */
const MAX_GROWN = 32;

/** How a selection paints: indices painted with a mode (subtract takes it away); true when something changed. @typedef {(indices: Iterable<number>, mode: string, subtract: boolean) => boolean} Paint */

/**
 * A Grow that Shrink can take back: the selection before it, the role it grew, and the selection's vertex count and
 * version right after it.
 * @typedef {{before: import('./selection.js').SelectionCopy, role: string, n: number, version: number}} Grown
 */

export class SurfaceSelection {
  /**
   * @param {object} opts
   * @param {import('./viewer.js').Viewer} opts.viewer
   * @param {import('./selection.js').Selection} opts.selection
   * @param {() => string} opts.role the role being painted
   * @param {() => void} opts.changed after the selection changed (refresh and send it)
   * @param {Paint|null} [opts.paint] paints (Selection.paint by default)
   */
  constructor({ viewer, selection, role, changed, paint = null }) {
    this.viewer = viewer;
    this.selection = selection;
    /** @type {Paint} */
    this.paint = paint ?? ((indices, mode, subtract) => selection.paint(indices, mode, subtract));
    this.role = role;
    this.changed = changed;
    /** @type {{ptr: Int32Array, adj: Int32Array}|null} */
    this._graph = null;
    /** @type {Uint32Array|null} the triangles `_graph` was built from */
    this._graphFor = null;
    /** The selection as it was before each Grow still undone by Shrink, newest last (see ring). */
    /** @type {Grown[]} */
    this._grown = [];
  }

  /** The vertex adjacency of the current mesh, built on first use after each new mesh. */
  graph() {
    const faces = this.viewer.faces;
    if (!faces) throw new Error('no mesh: no vertex adjacency');
    let graph = this._graph;
    if (!graph || this._graphFor !== faces) {
      const t0 = performance.now();
      graph = this._graph = buildAdjacency(faces, this.viewer.nVertices);
      this.buildMs = performance.now() - t0;
      this._graphFor = faces;
    }
    return graph;
  }

  /**
   * Membership test of the role being painted, or null for erase.
   * @returns {((i: number) => boolean)|null}
   */
  _member() {
    const s = this.selection;
    const role = this.role();
    if (role === 'roi') return (/** @type {number} */ i) => s.roi[i] === 1;
    const value = s.roleValue(role);
    if (value === null || value === 0) return null;
    return (/** @type {number} */ i) => s.role[i] === value;
  }

  /**
   * Grow (or shrink) the role being painted by one ring of edges; false when nothing changed. Shrink right after Grow
   * (nothing else edited in between) takes away exactly the layer Grow added, giving back what it painted over, so
   * Grow, Grow, Shrink, Shrink ends where it began; otherwise Shrink takes away the members with a neighbour outside.
   * @param {boolean} shrink
   */
  ring(shrink) {
    const member = this._member();
    if (!member || !this.viewer.nVertices) return false;
    const s = this.selection;
    const role = this.role();
    const last = this._grown[this._grown.length - 1];
    if (last && (last.version !== s.version || last.role !== role || last.n !== s.n)) this._grown = [];
    if (shrink && this._grown.length) {
      s.restored(/** @type {Grown} */ (this._grown.pop()).before);
      this.changed();
      if (this._grown.length) this._grown[this._grown.length - 1].version = s.version;
      return true;
    }
    const before = shrink ? null : s.copy();
    const ring = ringAround(this.graph(), this.viewer.nVertices, member, shrink);
    if (!this.paint(ring, role, shrink)) return false;
    this.changed();
    if (before) {
      this._grown.push({ before, role, n: s.n, version: s.version });
      if (this._grown.length > MAX_GROWN) this._grown.shift();
    }
    return true;
  }

  /**
   * The region of interest becomes the handles' surroundings: every vertex within `amount` rings (mode "rings")
   * or within `amount` percent of the bounding-box diagonal along the surface (mode "distance") of a handle
   * vertex (or corner of a point handle's triangle), anchors included. False when there are no handles.
   * @param {string} mode one of ROI_GROW_MODES
   * @param {number} amount
   */
  roiFromHandles(mode, amount) {
    const s = this.selection;
    /** @type {number[]} */
    const handles = [];
    for (let i = 0; i < s.n; i++) if (s.role[i] >= HANDLE0) handles.push(i);
    const faces = this.viewer.faces;
    for (const g of s.groups) {
      if (g.point && faces) for (let k = 0; k < 3; k++) handles.push(faces[3 * g.point.face + k]);
    }
    const box = this.viewer.box;
    if (!handles.length || !box) return false;
    let region;
    if (mode === 'rings') region = kRing(this.graph(), handles, Math.max(0, Math.round(amount)));
    else {
      const radius = (amount / 100) * box.min.distanceTo(box.max);
      region = geodesicDistances(this.graph(), this.viewer.positions, handles.map((v) => [v, 0]), radius).vertices;
    }
    s.clear('roi');
    this.paint(region, 'roi', false);
    const kept = handles.slice(); // the handles and anchors are in it whatever the distance
    for (let i = 0; i < s.n; i++) if (s.role[i] === FIXED) kept.push(i);
    s.paint(kept, 'roi', false);
    this.changed();
    return true;
  }
}

/**
 * Wire the panel's controls: the brush metric drop-down, the grow/shrink buttons and the region-of-interest row.
 * @param {SurfaceSelection} surface
 * @param {import('./tools.js').SelectionTools} tools
 * @param {(text: string) => void} tell shows a short message
 */
export function installSurfaceControls(surface, tools, tell) {
  const metric = byIdAs('brush-metric', HTMLSelectElement);
  metric.addEventListener('change', () => tools.metricChosen(metric.value));
  byId('btn-grow').addEventListener('click', () => surface.ring(false));
  byId('btn-shrink').addEventListener('click', () => surface.ring(true));
  byId('btn-roi-from-handles').addEventListener('click', () => {
    const amount = Number(byIdAs('roi-amount', HTMLInputElement).value);
    if (!(amount >= 0)) return tell('Give a number of rings or a distance of at least 0.');
    if (!surface.roiFromHandles(byIdAs('roi-mode', HTMLSelectElement).value, amount)) tell('Paint a handle first: the region grows from it.');
    return undefined;
  });
}
