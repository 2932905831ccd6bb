// Transform gizmo on the active handle group and the per-group transforms sent while dragging. The group's matrix
// is the one source of truth: the gizmo's pivot object is placed from it (and from the group's vertices), moved
// by the pointer, and each move turns into the matrix again.
import * as THREE from 'three';
import { RingControls } from './ringcontrols.js';
import { gridStep, rotationOf } from './transform.js';

const IDENTITY = new THREE.Matrix4().elements.slice();

export class HandleGizmo {
  /** @type {(THREE.Vector3|null)[]} per group: the placed pivot in the group's untransformed frame, or null (the centroid) */
  #pivots = [];
  /** @type {THREE.Matrix4[]} one per client handle group */
  #matrices = [];

  /**
   * @param {import('./viewer.js').Viewer} viewer
   * @param {{onDragStart?: () => boolean|void, onDrag: () => void, onDragEnd: () => void,
   *   onDraggingChanged?: (dragging: boolean) => void, onPivot?: () => void}} opts onDragStart() (return false to
   *   refuse the drag), onDrag(), onDragEnd(), onDraggingChanged(bool), onPivot() (the active group's pivot was
   *   placed or reset)
   */
  constructor(viewer, opts) {
    this.viewer = viewer;
    this.opts = opts;
    this.pivot = new THREE.Object3D();
    viewer.scene.add(this.pivot);
    this.controls = new RingControls(viewer.camera, viewer.canvas);
    this.controls.setSize(0.75);
    this.helper = this.controls.getHelper();
    viewer.scene.add(this.helper);
    this.marker = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 12),
      new THREE.MeshBasicMaterial({ color: 0xffffff, depthTest: false, transparent: true, opacity: 0.9 }));
    this.marker.renderOrder = 10;
    this.marker.visible = false;
    this.marker.raycast = () => {};
    this.marker.onBeforeRender = () => { // a constant size on screen, whatever the zoom
      this.marker.scale.setScalar(6 * viewer.worldPerPixel(this.marker.position));
      this.marker.updateMatrixWorld(true);
    };
    viewer.scene.add(this.marker);
    this.group = -1;
    /** @type {number[]} */
    this.indices = [];
    this.previewing = false;
    /** @type {{indices: number[], xyz: Float32Array}|null} the group's positions before a preview */
    this._saved = null;
    /** @type {number[]|null} */
    this.weights = null;
    this._base = new THREE.Matrix4();
    this._baseInv = new THREE.Matrix4();
    this._start = new THREE.Matrix4();
    this.controls.addEventListener('change', () => viewer.requestRender());
    this.controls.addEventListener('dragging-changed', (e) => {
      if (viewer.controls) viewer.controls.enabled = !e.value;
      opts.onDraggingChanged?.(/** @type {boolean} */ (e.value));
    });
    this.refused = false;
    this.controls.addEventListener('mouseDown', () => {
      this._begin();
      this.refused = opts.onDragStart?.() === false;
    });
    this.controls.addEventListener('objectChange', () => this._changed());
    this.controls.addEventListener('mouseUp', () => {
      if (!this.refused) {
        opts.onDragEnd();
        return;
      }
      this.refused = false;
      setTimeout(() => this.recenter(), 0); // put the gizmo back once the controls have let go
    });
  }

  /**
   * Per group, its placed pivot in the group's untransformed frame, or null (it turns about its centroid). Only the
   * gizmo writes them (placePivot, resetPivot, restorePivots, pivotFollowed …).
   * @returns {ReadonlyArray<Readonly<THREE.Vector3>|null>}
   */
  get pivots() {
    return this.#pivots;
  }

  /**
   * Per client handle group, its whole transform. Only the gizmo writes them (a drag, apply, setTransforms,
   * setMatrix …).
   * @returns {ReadonlyArray<Readonly<THREE.Matrix4>>}
   */
  get matrices() {
    return this.#matrices;
  }

  /**
   * Group g's whole transform becomes `matrix` (copied): a turn about a picture's pin, the mirror image of the
   * partner's (mirror editing). Groups that do not exist are ignored.
   * @param {number} g
   * @param {THREE.Matrix4} matrix
   */
  setMatrix(g, matrix) {
    this.#matrices[g]?.copy(matrix);
  }

  get dragging() {
    return this.controls.dragging;
  }

  /** True while the pointer is over or holding the gizmo. */
  get active() {
    return this.controls.dragging || (this.controls.object !== undefined && this.controls.axis !== null);
  }

  /** @param {'translate'|'rotate'|'scale'} mode */
  setMode(mode) {
    this.controls.setMode(mode);
  }

  /** Axes of the gizmo: 'world', or 'local' (the axes of the group's accumulated rotation). */
  get space() {
    return this.controls.space;
  }

  /** @param {'world'|'local'} space */
  setSpace(space) {
    this.controls.setSpace(space);
    this.recenter();
  }

  /**
   * Snap every move (true), or only while Ctrl/⌘ is held (false).
   * @param {boolean} on
   */
  setSnap(on) {
    this.controls.snapAlways = on;
  }

  get gridStep() {
    return this.controls.gridStep;
  }

  /** A new mesh: placed pivots are dropped and the translation grid follows the model's size. */
  meshChanged() {
    this._saved = null; // a preview's positions belong to the mesh gone
    this.previewing = false;
    this.#pivots = this.#matrices.map(() => null);
    this.controls.gridStep = gridStep(this.viewer.geometry?.boundingBox ?? null);
  }

  /**
   * Keep one matrix per client group, new groups start at identity.
   * @param {number} nGroups
   */
  syncGroups(nGroups) {
    while (this.#matrices.length < nGroups) this.#matrices.push(new THREE.Matrix4());
    this.#matrices.length = nGroups;
    while (this.#pivots.length < nGroups) this.#pivots.push(null);
    this.#pivots.length = nGroups;
  }

  /** Every group back to identity (a new constraint set: its frame is the current pose); pivots stay put. */
  resetTransforms() {
    this.#matrices.forEach((m, g) => {
      if (this.#pivots[g]) this.#pivots[g].applyMatrix4(m);
      m.identity();
    });
  }

  /**
   * Server transforms (server group k = client group groupMap[k]).
   * @param {number[][]|null|undefined} transforms column-major 4×4 per server group
   * @param {number[]} groupMap
   */
  setTransforms(transforms, groupMap) {
    for (const m of this.#matrices) m.identity();
    (transforms || []).forEach((t, k) => {
      const g = groupMap[k];
      if (g !== undefined && this.#matrices[g] && Array.isArray(t) && t.length === 16) this.#matrices[g].fromArray(t);
    });
    this.recenter();
  }

  /**
   * Attach to client group g with vertex indices (empty: hide the gizmo); `weights` (one per index) puts the pivot
   * at that combination of their positions instead of their centroid (a point handle: its triangle's corners and
   * barycentric coordinates).
   * @param {number} g
   * @param {number[]} indices
   * @param {number[]|null} [weights]
   */
  attach(g, indices, weights = null) {
    this.group = g;
    this.indices = indices;
    this.weights = weights;
    if (!indices.length || !this.viewer.mesh) {
      this.controls.detach();
      this.marker.visible = false;
      this.viewer.requestRender();
      return;
    }
    if (!this.controls.dragging) this.recenter();
    if (this.controls.object !== this.pivot) this.controls.attach(this.pivot);
    this.viewer.requestRender();
  }

  /** True when the active group has a placed pivot (rather than its centroid). */
  get pivotPlaced() {
    return !!this.#pivots[this.group];
  }

  /**
   * Turn the active group about the world point p from now on.
   * @param {number[]} p
   */
  placePivot(p) {
    const m = this.#matrices[this.group];
    if (!m || !this.indices.length) return;
    this.#pivots[this.group] = new THREE.Vector3(p[0], p[1], p[2]).applyMatrix4(m.clone().invert());
    this.opts.onPivot?.();
    this.recenter();
  }

  /** Per group, its placed pivot where it is now (world [x, y, z]), or null where it turns about its centroid. */
  placedPivots() {
    return this.#pivots.map((q, g) => (q ? q.clone().applyMatrix4(this.#matrices[g] || new THREE.Matrix4()).toArray() : null));
  }

  /**
   * Put back pivots that `placedPivots` gave (world points of the current shape), after a new constraint set made
   * the current shape every group's frame; entries for groups that do not exist are ignored.
   * @param {(number[]|null)[]|null|undefined} points
   */
  restorePivots(points) {
    (points || []).forEach((p, g) => {
      if (g >= this.#pivots.length || !Array.isArray(p) || p.length !== 3 || !p.every(Number.isFinite)) return;
      this.#pivots[g] = new THREE.Vector3(p[0], p[1], p[2]).applyMatrix4((this.#matrices[g] || new THREE.Matrix4()).clone().invert());
    });
    this.recenter();
  }

  /**
   * Group g's pivot follows another group's (mirror editing: the mirror image of its partner's): `pivot` in g's
   * untransformed frame, or null for its centroid. Groups that do not exist are ignored.
   * @param {number} g
   * @param {THREE.Vector3|null} pivot
   */
  pivotFollowed(g, pivot) {
    if (g < 0 || g >= this.#pivots.length) return;
    this.#pivots[g] = pivot;
  }

  /** The active group's pivot back to its centroid. */
  resetPivot() {
    if (this.group >= 0 && this.group < this.#pivots.length) this.#pivots[this.group] = null;
    this.opts.onPivot?.();
    this.recenter();
  }

  /** Put the pivot at the group's placed pivot or at its centroid (a point handle: its point). */
  recenter() {
    if (this.controls.dragging || this.previewing || !this.indices.length) return;
    const m = this.#matrices[this.group] || new THREE.Matrix4();
    const placed = this.#pivots[this.group];
    if (placed) this.pivot.position.copy(placed).applyMatrix4(m);
    else this.pivot.position.fromArray(this.centroid);
    this.pivot.quaternion.copy(rotationOf(m)); // the local axes (world axes ignore it)
    this.pivot.scale.set(1, 1, 1);
    this.pivot.updateMatrixWorld(true);
    this._showMarker(!!placed);
    this.viewer.requestRender();
  }

  /** @param {boolean} on */
  _showMarker(on) {
    this.marker.visible = on;
    if (!on) return;
    this.marker.position.copy(this.pivot.position);
  }

  /** Centroid of the active group's current positions (a point handle: its point, the weighted corners). */
  get centroid() {
    const pos = this.viewer.positions;
    let x = 0;
    let y = 0;
    let z = 0;
    const n = this.indices.length;
    this.indices.forEach((i, k) => {
      const w = this.weights ? this.weights[k] : 1 / n;
      x += w * pos[3 * i];
      y += w * pos[3 * i + 1];
      z += w * pos[3 * i + 2];
    });
    return [x, y, z];
  }

  /** World position of the pivot the active group turns about. */
  get pivotWorld() {
    return this.pivot.position.toArray();
  }

  /**
   * Unit vector of axis 'x', 'y' or 'z' in the gizmo's space.
   * @param {string} letter
   */
  axisVector(letter) {
    const v = new THREE.Vector3(letter === 'x' ? 1 : 0, letter === 'y' ? 1 : 0, letter === 'z' ? 1 : 0);
    if (this.space === 'local') v.applyQuaternion(rotationOf(this.#matrices[this.group] || new THREE.Matrix4()));
    return v;
  }

  /**
   * Show the gizmo where `matrix` (the active group's whole transform) would put it, without sending it.
   * @param {THREE.Matrix4} matrix
   */
  preview(matrix) {
    const m = this.#matrices[this.group];
    if (!m || this.controls.dragging) return;
    if (!this.previewing) {
      this.recenter();
      this.pivot.updateMatrix();
      this._base.copy(this.pivot.matrix);
      this.previewing = true;
    }
    const delta = matrix.clone().multiply(m.clone().invert());
    if (!this.weights) this._moveHandle(delta); // a point handle's triangle is not its own: only the gizmo moves
    delta.multiply(this._base).decompose(this.pivot.position, this.pivot.quaternion, this.pivot.scale);
    this.pivot.updateMatrixWorld(true);
    this._showMarker(this.pivotPlaced);
    this.viewer.requestRender();
  }

  /**
   * Show the group's vertices moved rigidly by `delta` (their positions before the preview are kept).
   * @param {THREE.Matrix4} delta
   */
  _moveHandle(delta) {
    const pos = this.viewer.positions;
    let saved = this._saved;
    if (!saved) {
      const xyz = Float32Array.from(this.indices.flatMap((i) => [pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]]));
      saved = this._saved = { indices: this.indices, xyz };
    }
    const { xyz } = saved;
    const v = new THREE.Vector3();
    saved.indices.forEach((i, k) => {
      v.fromArray(xyz, 3 * k).applyMatrix4(delta);
      pos[3 * i] = v.x;
      pos[3 * i + 1] = v.y;
      pos[3 * i + 2] = v.z;
    });
    this.viewer.updatePositions(pos);
  }

  /** Drop the preview: the group's vertices and the gizmo go back to the group's transform. */
  cancelPreview() {
    const saved = this._saved;
    if (saved) {
      const pos = this.viewer.positions;
      saved.indices.forEach((i, k) => pos.set(saved.xyz.subarray(3 * k, 3 * k + 3), 3 * i));
      this.viewer.updatePositions(pos);
    }
    this._saved = null;
    this.previewing = false;
    this.recenter();
  }

  /**
   * Make `matrix` the active group's transform and send it as a whole drag (drag, then end_drag); false when the
   * drag is refused (the selection is not on the server yet).
   * @param {THREE.Matrix4} matrix
   */
  apply(matrix) {
    const m = this.#matrices[this.group];
    if (!m || this.controls.dragging) return false;
    if (this.opts.onDragStart?.() === false) {
      this.cancelPreview();
      return false;
    }
    this.preview(matrix);
    m.copy(matrix);
    this.opts.onDrag();
    this.opts.onDragEnd();
    this._saved = null; // the server's frames take over from the preview
    this.previewing = false;
    return true;
  }

  _begin() {
    this.pivot.updateMatrix();
    this._base.copy(this.pivot.matrix);
    this._baseInv.copy(this._base).invert();
    this._start.copy(this.#matrices[this.group] || new THREE.Matrix4());
  }

  _changed() {
    if (this.refused || this.group < 0 || !this.#matrices[this.group]) return;
    this.pivot.updateMatrix();
    this.#matrices[this.group].multiplyMatrices(this.pivot.matrix, this._baseInv).multiply(this._start);
    if (this.pivotPlaced) this._showMarker(true);
    this.opts.onDrag();
  }

  /**
   * The drag payload: one column-major 4×4 per server group.
   * @param {number[]} groupMap
   * @returns {number[][]}
   */
  transformsFor(groupMap) {
    return groupMap.map((g) => (this.#matrices[g] ? Array.from(this.#matrices[g].elements) : IDENTITY.slice()));
  }
}
