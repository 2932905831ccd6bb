// Pointer tools on the 3D view: brush painting (raycast + radius) and box selection.
import * as THREE from 'three';
import { byId } from './dom.js';
import { connectedPatch, geodesicDistances, triangleSeeds } from './geodesic.js';

/** How the brush measures its radius: straight distance, distance along the surface, or the connected patch. */
export const BRUSH_METRICS = ['straight', 'surface', 'patch'];

/**
 * @typedef {{isGizmoActive: () => boolean, onPaint: (indices: number[], subtract: boolean) => void,
 *   onStrokeEnd: () => void, graph: () => {ptr: Int32Array, adj: Int32Array}, picking?: () => boolean,
 *   onPick: (hit: THREE.Intersection, subtract: boolean) => void}} ToolsOptions
 */

export class SelectionTools {
  // Only this class writes its fields: the page tells it what the user chose through its methods (toolChosen,
  // unitsChosen, brushSized, frontOnlyChosen, metricChosen).
  /** @type {import('./viewer.js').Viewer} */
  #viewer;
  /** @type {ToolsOptions} */
  #opts;
  #tool = 'brush';
  #radiusPx = 24;
  #units = 'screen';
  #worldRadiusFrac = 0.04;
  #frontOnly = true;
  #metric = 'straight';
  /** @type {THREE.Face|null} the face under the brush at its last raycast (null: unknown) */
  #hitFace = null;
  #erasing = false;
  #painting = false;
  /** @type {{x0: number, y0: number, x1: number, y1: number, subtract: boolean}|null} the box being dragged */
  #box = null;
  #picked = false;
  #raycaster = new THREE.Raycaster();
  #cursorEl = byId('brush-cursor');
  #rectEl = byId('box-rect');
  /** @type {number[]|null} the pointer position waiting for the next animation frame's raycast */
  #queued = null;

  /**
   * @param {import('./viewer.js').Viewer} viewer
   * @param {ToolsOptions} opts isGizmoActive(): bool,
   *   onPaint(indices, subtract), onStrokeEnd(), graph(): the mesh's adjacency (geodesic.js buildAdjacency),
   *   picking(): true when a click places a point instead of painting, onPick(hit, subtract) (the raycast
   *   intersection under a click in that mode)
   */
  constructor(viewer, opts) {
    this.#viewer = viewer;
    this.#opts = opts;
    const c = viewer.canvas;
    c.addEventListener('pointerdown', (e) => this._down(e));
    c.addEventListener('pointermove', (e) => this._move(e));
    c.addEventListener('pointerup', (e) => this._up(e));
    c.addEventListener('pointercancel', (e) => this._up(e));
    c.addEventListener('pointerleave', () => this._hideCursor());
    c.addEventListener('contextmenu', (e) => e.preventDefault());
  }

  /** The pointer tool: 'brush', 'box' or 'orbit'. */
  get tool() {
    return this.#tool;
  }

  /** What the brush radius is measured in: 'screen' (pixels) or 'world' (a fraction of the model's size). */
  get units() {
    return this.#units;
  }

  /** The brush radius in pixels (units 'screen'). */
  get radiusPx() {
    return this.#radiusPx;
  }

  /** The brush radius as a fraction of the model's bounding-box diagonal (units 'world'). */
  get worldRadiusFrac() {
    return this.#worldRadiusFrac;
  }

  /** The brush and the box take front-facing vertices only. */
  get frontOnly() {
    return this.#frontOnly;
  }

  /** How the brush measures its radius: one of BRUSH_METRICS. */
  get metric() {
    return this.#metric;
  }

  /**
   * The user chose the pointer tool.
   * @param {string} tool
   */
  toolChosen(tool) {
    this.#tool = tool;
    this._hideCursor();
  }

  /**
   * The user chose what the brush radius is measured in ('screen' or 'world').
   * @param {string} units
   */
  unitsChosen(units) {
    this.#units = units;
  }

  /**
   * The user sized the brush in its current units: pixels, or percent of the model's size.
   * @param {number} radius
   */
  brushSized(radius) {
    if (this.#units === 'world') this.#worldRadiusFrac = radius / 100;
    else this.#radiusPx = radius;
  }

  /**
   * The user chose whether the brush and the box take front-facing vertices only.
   * @param {boolean} on
   */
  frontOnlyChosen(on) {
    this.#frontOnly = on;
  }

  /**
   * The user chose how the brush measures its radius (one of BRUSH_METRICS).
   * @param {string} metric
   */
  metricChosen(metric) {
    this.#metric = metric;
  }

  /** @param {PointerEvent} e */
  _local(e) {
    const r = this.#viewer.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  /**
   * The nearest intersection of the mesh under canvas pixel (x, y), or null.
   * @param {number} x
   * @param {number} y
   */
  _intersect(x, y) {
    const v = this.#viewer;
    if (!v.mesh) return null;
    const ndc = new THREE.Vector2((x / v.canvas.clientWidth) * 2 - 1, -(y / v.canvas.clientHeight) * 2 + 1);
    this.#raycaster.setFromCamera(ndc, v.camera);
    const hits = this.#raycaster.intersectObject(v.mesh, false);
    return hits.length ? hits[0] : null;
  }

  /**
   * @param {number} x
   * @param {number} y
   */
  _hit(x, y) {
    const hit = this._intersect(x, y);
    this.#hitFace = hit?.face ?? null;
    return hit ? hit.point : null;
  }

  get _picking() {
    return this.#tool !== 'orbit' && !!this.#opts.picking?.();
  }

  /**
   * World-space brush radius at a point.
   * @param {THREE.Vector3} point
   */
  worldRadius(point) {
    const box = this.#viewer.box;
    if (this.#units === 'world' && box) return this.#worldRadiusFrac * box.min.distanceTo(box.max);
    return this.#radiusPx * this.#viewer.worldPerPixel(point);
  }

  /** @param {PointerEvent} e */
  _down(e) {
    if (e.button !== 0 || !this.#viewer.mesh) return;
    const [x, y] = this._local(e);
    const subtract = e.ctrlKey || e.metaKey || e.altKey;
    // a point handle's marker lies under its gizmo: removing it must reach through
    if (this.#opts.isGizmoActive() && !(this._picking && subtract)) return;
    if (this._picking) {
      const hit = this._intersect(x, y);
      if (!hit) return; // empty space: let the camera orbit
      this.#picked = true;
      this._takePointer(e);
      this.#opts.onPick(hit, subtract);
      return;
    }
    if (e.shiftKey || this.#tool === 'box') {
      this.#box = { x0: x, y0: y, x1: x, y1: y, subtract };
      this._takePointer(e);
      this._drawRect(this.#box);
      return;
    }
    if (this.#tool !== 'brush') return;
    // just off the silhouette (the brush's circle reaches the model) the stroke starts at the nearest vertex;
    // farther out it is empty space: let the camera orbit
    const p = this._hit(x, y) ?? this._nearby(x, y);
    if (!p) return;
    this.#painting = true;
    this.#erasing = subtract;
    this._takePointer(e);
    this._paintAt(p);
  }

  /** The brush's radius in canvas pixels (at the model's centre for a radius in model units). */
  _radiusPx() {
    const box = this.#viewer.box;
    if (this.#units !== 'world' || !box) return this.#radiusPx;
    const centre = box.getCenter(new THREE.Vector3());
    return this.worldRadius(centre) / this.#viewer.worldPerPixel(centre);
  }

  /**
   * The position of the vertex that shows nearest to canvas pixel (x, y) within the brush's radius (at least a few
   * pixels; front-facing ones only with `frontOnly`), or null: a press that misses the surface but whose brush
   * circle reaches the model. The face under the brush is then unknown (`_hitFace` null: straight distances).
   * @param {number} x
   * @param {number} y
   */
  _nearby(x, y) {
    const v = this.#viewer;
    if (!v.geometry) return null;
    const reach = Math.max(6, this._radiusPx());
    const w = v.canvas.clientWidth;
    const h = v.canvas.clientHeight;
    const m = new THREE.Matrix4().multiplyMatrices(v.camera.projectionMatrix, v.camera.matrixWorldInverse).elements;
    const cam = v.camera.position;
    const pos = v.positions;
    const nrm = v.geometry.attributes.normal.array;
    let best = -1;
    let bestD = reach * reach;
    for (let i = 0, n = pos.length / 3; i < n; i++) {
      const px = pos[3 * i];
      const py = pos[3 * i + 1];
      const pz = pos[3 * i + 2];
      const cw = m[3] * px + m[7] * py + m[11] * pz + m[15];
      if (cw <= 0) continue;
      const dx = (((m[0] * px + m[4] * py + m[8] * pz + m[12]) / cw + 1) / 2) * w - x;
      const dy = ((1 - (m[1] * px + m[5] * py + m[9] * pz + m[13]) / cw) / 2) * h - y;
      const d = dx * dx + dy * dy;
      if (d > bestD) continue;
      if (this.#frontOnly
        && nrm[3 * i] * (cam.x - px) + nrm[3 * i + 1] * (cam.y - py) + nrm[3 * i + 2] * (cam.z - pz) < 0) continue;
      best = i;
      bestD = d;
    }
    this.#hitFace = null;
    return best < 0 ? null : new THREE.Vector3(pos[3 * best], pos[3 * best + 1], pos[3 * best + 2]);
  }

  /** @param {PointerEvent} e */
  _takePointer(e) {
    e.stopImmediatePropagation();
    if (this.#viewer.controls) this.#viewer.controls.enabled = false;
    this.#viewer.canvas.setPointerCapture(e.pointerId);
  }

  /** @param {PointerEvent} e */
  _move(e) {
    const [x, y] = this._local(e);
    if (this.#box) {
      this.#box.x1 = x;
      this.#box.y1 = y;
      this._drawRect(this.#box);
      return;
    }
    if (this.#tool === 'brush' && !this.#opts.isGizmoActive() && !this._picking) this._showCursor(x, y, e.ctrlKey || e.metaKey || e.altKey);
    else this._hideCursor();
    if (!this.#painting) return;
    // coalesce to one raycast per animation frame
    if (this.#queued) {
      this.#queued = [x, y];
      return;
    }
    this.#queued = [x, y];
    requestAnimationFrame(() => {
      const q = this.#queued;
      this.#queued = null;
      if (!this.#painting || !q) return;
      const p = this._hit(q[0], q[1]);
      if (p) this._paintAt(p);
    });
  }

  /** @param {PointerEvent} e */
  _up(e) {
    if (this.#picked) {
      this.#picked = false;
      this._release(e);
      return;
    }
    if (this.#box) {
      const b = this.#box;
      this.#box = null;
      this.#rectEl.hidden = true;
      this._release(e);
      const indices = this.boxIndices(b.x0, b.y0, b.x1, b.y1);
      this.#opts.onPaint(indices, b.subtract);
      this.#opts.onStrokeEnd();
      return;
    }
    if (this.#painting) {
      this.#painting = false;
      this.#queued = null;
      this._release(e);
      this.#opts.onStrokeEnd();
    }
  }

  /** @param {PointerEvent} e */
  _release(e) {
    if (this.#viewer.controls) this.#viewer.controls.enabled = true;
    if (this.#viewer.canvas.hasPointerCapture(e.pointerId)) this.#viewer.canvas.releasePointerCapture(e.pointerId);
  }

  /** @param {THREE.Vector3} p */
  _paintAt(p) {
    const r = this.worldRadius(p);
    const pos = this.#viewer.positions;
    if (this.#metric !== 'straight' && this.#hitFace) {
      const seeds = triangleSeeds(pos, this.#hitFace, p);
      const graph = this.#opts.graph();
      const out = this.#metric === 'surface'
        ? geodesicDistances(graph, pos, seeds, r).vertices
        : connectedPatch(graph, pos, seeds.map(([v]) => v), p, r);
      this.#opts.onPaint(out, this.#erasing);
      return;
    }
    const r2 = r * r;
    /** @type {number[]} */
    const out = [];
    for (let i = 0, n = pos.length / 3; i < n; i++) {
      const dx = pos[3 * i] - p.x;
      const dy = pos[3 * i + 1] - p.y;
      const dz = pos[3 * i + 2] - p.z;
      if (dx * dx + dy * dy + dz * dz <= r2) out.push(i);
    }
    this.#opts.onPaint(out, this.#erasing);
  }

  /**
   * Vertices whose projection falls inside the screen rectangle (optionally front-facing only).
   * @param {number} x0
   * @param {number} y0
   * @param {number} x1
   * @param {number} y1
   * @returns {number[]}
   */
  boxIndices(x0, y0, x1, y1) {
    const v = this.#viewer;
    const w = v.canvas.clientWidth;
    const h = v.canvas.clientHeight;
    const xa = Math.min(x0, x1);
    const xb = Math.max(x0, x1);
    const ya = Math.min(y0, y1);
    const yb = Math.max(y0, y1);
    if (xb - xa < 2 || yb - ya < 2) return [];
    const m = new THREE.Matrix4().multiplyMatrices(v.camera.projectionMatrix, v.camera.matrixWorldInverse).elements;
    const cam = v.camera.position;
    const pos = v.positions;
    if (!v.geometry) return [];
    const nrm = v.geometry.attributes.normal.array;
    const out = [];
    for (let i = 0, n = pos.length / 3; i < n; i++) {
      const px = pos[3 * i];
      const py = pos[3 * i + 1];
      const pz = pos[3 * i + 2];
      const cw = m[3] * px + m[7] * py + m[11] * pz + m[15];
      if (cw <= 0) continue;
      const sx = (((m[0] * px + m[4] * py + m[8] * pz + m[12]) / cw + 1) / 2) * w;
      const sy = ((1 - (m[1] * px + m[5] * py + m[9] * pz + m[13]) / cw) / 2) * h;
      if (sx < xa || sx > xb || sy < ya || sy > yb) continue;
      if (this.#frontOnly) {
        const facing = nrm[3 * i] * (cam.x - px) + nrm[3 * i + 1] * (cam.y - py) + nrm[3 * i + 2] * (cam.z - pz);
        if (facing <= 0) continue;
      }
      out.push(i);
    }
    return out;
  }

  /** @param {{x0: number, y0: number, x1: number, y1: number}} b */
  _drawRect(b) {
    const s = this.#rectEl.style;
    s.left = `${Math.min(b.x0, b.x1)}px`;
    s.top = `${Math.min(b.y0, b.y1)}px`;
    s.width = `${Math.abs(b.x1 - b.x0)}px`;
    s.height = `${Math.abs(b.y1 - b.y0)}px`;
    this.#rectEl.hidden = false;
  }

  /**
   * @param {number} x
   * @param {number} y
   * @param {boolean} erase
   */
  _showCursor(x, y, erase) {
    let r = this.#radiusPx;
    if (this.#units === 'world' && this.#viewer.geometry) {
      const p = this._hit(x, y);
      if (!p) return this._hideCursor();
      r = this.worldRadius(p) / this.#viewer.worldPerPixel(p);
    }
    const s = this.#cursorEl.style;
    s.left = `${x}px`;
    s.top = `${y}px`;
    s.width = `${2 * r}px`;
    s.height = `${2 * r}px`;
    this.#cursorEl.classList.toggle('erase', erase);
    this.#cursorEl.hidden = false;
  }

  _hideCursor() {
    this.#cursorEl.hidden = true;
  }
}
