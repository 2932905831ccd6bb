// Transform gizmo on the active handle group and the per-group transforms sent while dragging.
import * as THREE from 'three';
import { TransformControls } from 'three/addons/controls/TransformControls.js';

const IDENTITY = new THREE.Matrix4().elements.slice();

export class HandleGizmo {
  /**
   * @param {import('./viewer.js').Viewer} viewer
   * @param {object} opts onDragStart() (return false to refuse the drag), onDrag(), onDragEnd(),
   *   onDraggingChanged(bool)
   */
  constructor(viewer, opts) {
    this.viewer = viewer;
    this.opts = opts;
    this.pivot = new THREE.Object3D();
    viewer.scene.add(this.pivot);
    this.controls = new TransformControls(viewer.camera, viewer.canvas);
    this.controls.setSize(0.75);
    this.helper = this.controls.getHelper();
    viewer.scene.add(this.helper);
    this.matrices = []; // one THREE.Matrix4 per client handle group
    this.group = -1;
    this.indices = [];
    this.weights = null;
    this._base = new THREE.Matrix4();
    this._baseInv = new THREE.Matrix4();
    this._start = new THREE.Matrix4();
    this.controls.addEventListener('change', () => viewer.requestRender());
    this.controls.addEventListener('dragging-changed', (e) => {
      if (viewer.controls) viewer.controls.enabled = !e.value;
      opts.onDraggingChanged?.(e.value);
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

  get dragging() {
    return this.controls.dragging;
  }

  /** True while the pointer is over or holding the gizmo. */
  get active() {
    return this.controls.dragging || (this.controls.object !== undefined && this.controls.axis !== null);
  }

  setMode(mode) {
    this.controls.setMode(mode);
  }

  /** Keep one matrix per client group, new groups start at identity. */
  syncGroups(nGroups) {
    while (this.matrices.length < nGroups) this.matrices.push(new THREE.Matrix4());
    this.matrices.length = nGroups;
  }

  resetTransforms() {
    for (const m of this.matrices) m.identity();
  }

  /** Server transforms (server group k = client group groupMap[k]). */
  setTransforms(transforms, groupMap) {
    this.resetTransforms();
    (transforms || []).forEach((t, k) => {
      const g = groupMap[k];
      if (g !== undefined && this.matrices[g] && Array.isArray(t) && t.length === 16) this.matrices[g].fromArray(t);
    });
  }

  /**
   * Attach to client group g with vertex indices (empty: hide the gizmo); `weights` (one per index) puts the pivot
   * at that combination of their positions instead of their centroid (a point handle: its triangle's corners and
   * barycentric coordinates).
   */
  attach(g, indices, weights = null) {
    this.group = g;
    this.indices = indices;
    this.weights = weights;
    if (!indices.length || !this.viewer.mesh) {
      this.controls.detach();
      this.viewer.requestRender();
      return;
    }
    if (!this.controls.dragging) this.recenter();
    if (this.controls.object !== this.pivot) this.controls.attach(this.pivot);
    this.viewer.requestRender();
  }

  /** Put the pivot at the centroid of the group's current positions (or their weighted combination). */
  recenter() {
    if (this.controls.dragging || !this.indices.length) return;
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
    this.pivot.position.set(x, y, z);
    this.pivot.quaternion.identity();
    this.pivot.scale.set(1, 1, 1);
    this.pivot.updateMatrixWorld(true);
    this.viewer.requestRender();
  }

  get centroid() {
    return this.pivot.position.toArray();
  }

  _begin() {
    this.pivot.updateMatrix();
    this._base.copy(this.pivot.matrix);
    this._baseInv.copy(this._base).invert();
    this._start.copy(this.matrices[this.group] || new THREE.Matrix4());
  }

  _changed() {
    if (this.refused || this.group < 0 || !this.matrices[this.group]) return;
    this.pivot.updateMatrix();
    this.matrices[this.group].multiplyMatrices(this.pivot.matrix, this._baseInv).multiply(this._start);
    this.opts.onDrag();
  }

  /** The drag payload: one column-major 4×4 per server group. */
  transformsFor(groupMap) {
    return groupMap.map((g) => (this.matrices[g] ? Array.from(this.matrices[g].elements) : IDENTITY.slice()));
  }
}
