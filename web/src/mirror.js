// Mirror editing: with it on, painting, box selection and growing a role act on both sides of the mirror plane,
// a handle group painted on one side gets a partner group on the other, and dragging a group moves its partner by
// the mirrored transform. The plane and the vertex correspondence (symmetry.js) are found once per rest pose, when
// mirror editing is first turned on, with the tolerance set in the panel: how far a vertex's reflection may lie from
// the surface for the vertex to have a partner.
import * as THREE from 'three';
import { byId, byIdAs } from './dom.js';
import { ignoreTypeAhead } from './keys.js';
import {
  DEFAULT_TOLERANCE, detectSymmetry, MIN_MATCHED, mirrorImage, reflectionMatrix, TOLERANCE_RANGE,
} from './symmetry.js';

/** Key of the handle-group pairs in a constraints document's "meta" object: [[k, l], ...] of handle_groups. */
export const PARTNERS_KEY = 'mirror_partners';

const pct = (/** @type {number} */ x) => `${(100 * x).toFixed(x > 0.995 && x < 1 ? 1 : 0)}%`;

export class MirrorEditing {
  /**
   * @param {{viewer: import('./viewer.js').Viewer, selection: import('./selection.js').Selection,
   *   tell: (text: string) => void, checkbox?: HTMLInputElement, axisSelect?: HTMLSelectElement,
   *   toleranceInput?: HTMLInputElement, statusEl?: HTMLElement}} opts viewer, selection, tell(text) (a short
   *   message), checkbox, axisSelect, toleranceInput (percent of the bounding-box diagonal), statusEl
   */
  constructor({
    viewer, selection, tell,
    checkbox = byIdAs('mirror-on', HTMLInputElement),
    axisSelect = byIdAs('mirror-axis', HTMLSelectElement),
    toleranceInput = byIdAs('mirror-tolerance', HTMLInputElement),
    statusEl = byId('mirror-status'),
  }) {
    this.viewer = viewer;
    this.selection = selection;
    this.tell = tell;
    this.checkbox = checkbox;
    this.axisSelect = axisSelect;
    this.statusEl = statusEl;
    this.on = false;
    this.axis = 'auto';
    this.tolerance = DEFAULT_TOLERANCE; // a fraction of the bounding-box diagonal
    this.toleranceInput = toleranceInput;
    /** @type {ReturnType<typeof detectSymmetry>|null} detectSymmetry's answer for the rest pose, null until needed */
    this.result = null;
    /** @type {Float32Array|null} rest positions of the current mesh (its faces: `faces`) */
    this.rest = null;
    /** @type {number|null} the server's id of that rest pose (null until a state names it) */
    this.restId = null;
    /** @type {Map<number, Float32Array|null>} rest positions by id: undo and redo of an apply come back to an earlier one */
    this.rests = new Map();
    /** @type {ArrayLike<number>|null} */
    this.faces = null;
    this.matrix = new THREE.Matrix4();
    /** @type {THREE.Mesh<THREE.PlaneGeometry, THREE.MeshBasicMaterial>|null} */
    this.planeMesh = null;
    checkbox.addEventListener('change', () => this.setOn(checkbox.checked));
    axisSelect.addEventListener('change', () => this.setAxis(axisSelect.value));
    ignoreTypeAhead(axisSelect);
    toleranceInput.value = String(100 * this.tolerance);
    toleranceInput.addEventListener('change', () => {
      const pctValue = Number(toleranceInput.value);
      if (toleranceInput.value.trim() === '' || !Number.isFinite(pctValue)) {
        toleranceInput.value = String(100 * this.tolerance);
        return;
      }
      this.setTolerance(pctValue / 100);
    });
    this._show();
  }

  /** Mirror editing is on and has a plane. */
  get active() {
    return this.on && !!this.result?.plane;
  }

  /** The vertex correspondence (-1: no partner), or null while inactive. */
  get mirrorOf() {
    const r = this.result;
    return this.on && r?.plane ? r.mirrorOf : null;
  }

  /**
   * A new mesh: its positions are the rest pose.
   * @param {ArrayLike<number>} positions
   * @param {ArrayLike<number>} faces
   */
  meshChanged(positions, faces) {
    this.rest = Float32Array.from(positions);
    this.faces = faces;
    this.restId = null;
    this.rests.clear();
    this._invalidate();
  }

  /**
   * A state message: when it names another rest pose, the plane is found again on it. A rest pose seen before
   * (an undo or redo across an apply) comes back from memory; a new one (an apply) is the shape shown, which the apply
   * made the rest pose.
   * @param {number | undefined} restId the state's `rest_id`
   */
  stateArrived(restId) {
    if (typeof restId !== 'number' || restId === this.restId) return;
    if (this.restId === null) {
      this.restId = restId; // the first state of this mesh: its rest pose is the mesh's
      this.rests.set(restId, this.rest);
      return;
    }
    this.rest = this.rests.get(restId) ?? Float32Array.from(this.viewer.positions);
    this.rests.set(restId, this.rest);
    this.restId = restId;
    this._invalidate();
  }

  _invalidate() {
    this.result = null;
    if (this.on) this.setOn(true);
    else this._show();
  }

  /**
   * Turn mirror editing on (finding the plane first if needed; it stays off when none is found) or off.
   * @param {boolean} on
   */
  setOn(on) {
    this.on = on;
    if (on && !this.result && this.rest) {
      this.result = detectSymmetry(this.rest, this.faces, this.axis, this.tolerance);
      this.matrix.fromArray(this.result.plane ? reflectionMatrix(this.result.plane) : new THREE.Matrix4().elements);
      this.repair();
    }
    if (on && this.result && !this.result.plane) {
      this.on = false;
      this.tell(`No mirror symmetry found (the best plane matched ${pct(this.result.matched)} of the vertices); `
        + 'pick the X, Y or Z plane to mirror anyway.');
    }
    this._show();
  }

  /**
   * The plane: 'auto' (found) or 'x', 'y', 'z' (that axis's plane through the middle of the model).
   * @param {string} axis
   */
  setAxis(axis) {
    this.axis = axis;
    this.axisSelect.value = axis;
    this._invalidate();
  }

  /**
   * How far (a fraction of the bounding-box diagonal, clamped to TOLERANCE_RANGE) a vertex's reflection may lie from
   * the surface for the vertex to have a partner; the plane and the partners are found again with it.
   * @param {number} fraction
   */
  setTolerance(fraction) {
    const f = Math.min(TOLERANCE_RANGE.max, Math.max(TOLERANCE_RANGE.min, fraction));
    this.toleranceInput.value = String(Number((100 * f).toPrecision(3)));
    if (f === this.tolerance) return;
    this.tolerance = f;
    this._invalidate();
  }

  _show() {
    this.checkbox.checked = this.on;
    const r = this.result;
    let text;
    if (!r) text = this.on ? 'no mesh' : 'off';
    else if (!r.plane) text = `no symmetry found (best plane: ${pct(r.matched)} of the vertices matched)`;
    else {
      const n = r.plane.normal.map((c) => String(Number(c.toFixed(3)) || 0)).join(', ');
      const kind = r.matched >= MIN_MATCHED ? 'symmetric' : 'partly symmetric';
      text = `${kind}: ${pct(r.matched)} of the vertices matched (plane normal ${n})${this.on ? '' : ', off'}`;
    }
    this.statusEl.textContent = text;
    this.statusEl.title = r ? `found in ${r.ms.toFixed(0)} ms; a vertex has a partner when its reflection lies at `
      + `most ${r.tolerance.toPrecision(2)} from the surface (${Number((100 * this.tolerance).toPrecision(3))}% of `
      + 'the model\'s size)' : '';
    this._drawPlane();
  }

  _drawPlane() {
    const v = this.viewer;
    const plane = this.on ? this.result?.plane : null; // non-null just when active
    const rest = this.rest;
    if (!plane || !rest || !v.geometry) {
      if (this.planeMesh) this.planeMesh.visible = false;
      v.requestRender();
      return;
    }
    if (!this.planeMesh) {
      const material = new THREE.MeshBasicMaterial({
        color: 0x4c9aff, transparent: true, opacity: 0.16, side: THREE.DoubleSide, depthWrite: false,
      });
      this.planeMesh = new THREE.Mesh(new THREE.PlaneGeometry(1, 1), material);
      const edge = new THREE.LineSegments(new THREE.EdgesGeometry(this.planeMesh.geometry),
        new THREE.LineBasicMaterial({ color: 0x4c9aff, transparent: true, opacity: 0.6 }));
      this.planeMesh.add(edge);
      this.planeMesh.raycast = () => {};
      edge.raycast = () => {};
      this.planeMesh.renderOrder = 1;
      v.scene.add(this.planeMesh);
    }
    const { normal, point } = plane;
    const nrm = new THREE.Vector3(...normal);
    const box = new THREE.Box3().setFromArray(rest);
    const centre = box.getCenter(new THREE.Vector3());
    centre.addScaledVector(nrm, nrm.dot(new THREE.Vector3(...point).sub(centre)));
    const size = 1.15 * box.getSize(new THREE.Vector3()).length();
    this.planeMesh.position.copy(centre);
    this.planeMesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 0, 1), nrm);
    this.planeMesh.scale.set(size, size, 1);
    this.planeMesh.visible = true;
    v.requestRender();
  }

  /**
   * Paint like Selection.paint, and with mirror editing on the mirrored vertices too: for a handle group, into its
   * partner group (created and paired on first use); vertices painted directly keep the group they were painted.
   * @param {Iterable<number>} indices
   * @param {string} mode
   * @param {boolean} [subtract]
   * @returns {boolean} something changed
   */
  paint(indices, mode, subtract = false) {
    const s = this.selection;
    const mirrorOf = this.mirrorOf;
    if (!mirrorOf) return s.paint(indices, mode, subtract);
    const list = Array.from(indices);
    const image = mirrorImage(mirrorOf, list);
    if (mode !== 'handle') return s.paint(list.concat(image), mode, subtract);
    const direct = new Set(list);
    const mirrored = image.filter((j) => !direct.has(j));
    let changed = s.paint(list, mode, subtract);
    if (!mirrored.length) return changed;
    let p = s.partnerOf(s.activeGroup);
    if (p < 0) {
      if (subtract) return changed;
      p = s.partnerAdded(s.activeGroup);
      changed = true;
    }
    return s.paint(mirrored, mode, subtract, p) || changed;
  }

  /**
   * Clear a role (Selection.clear); with mirror editing on, a handle group's partner is cleared as well.
   * @param {string} mode
   */
  clear(mode) {
    const s = this.selection;
    const p = this.active && mode === 'handle' ? s.partnerOf(s.activeGroup) : -1;
    s.clear(mode);
    if (p >= 0) s.clear(mode, p);
  }

  /**
   * The active group's matrix changed (a drag, or any other edit of its transform): with mirror editing on, its
   * partner's becomes M·T·M (M the reflection, T the group's matrix), so one drag message carries both.
   * @param {{matrices: ReadonlyArray<Readonly<THREE.Matrix4>>, setMatrix: (g: number, m: THREE.Matrix4) => void}} gizmo
   * @param {number} group client handle group
   */
  follow(gizmo, group) {
    if (!this.active) return;
    const p = this.selection.partnerOf(group);
    const T = gizmo.matrices[group];
    if (p < 0 || !T || !gizmo.matrices[p]) return;
    gizmo.setMatrix(p, new THREE.Matrix4().multiplyMatrices(this.matrix, T).multiply(this.matrix));
  }

  /**
   * The active group's pivot was placed or reset: with mirror editing on, its partner's pivot becomes the mirror
   * image (or its centroid too), so dragging either side turns both about mirrored points.
   * @param {{pivots: ReadonlyArray<Readonly<THREE.Vector3>|null>,
   *   pivotFollowed: (g: number, pivot: THREE.Vector3|null) => void}} gizmo pivots in each group's untransformed frame
   * @param {number} group client handle group
   */
  followPivot(gizmo, group) {
    if (!this.active) return;
    const p = this.selection.partnerOf(group);
    if (p < 0 || p >= gizmo.pivots.length) return;
    const q = gizmo.pivots[group];
    gizmo.pivotFollowed(p, q ? q.clone().applyMatrix4(this.matrix) : null);
  }

  /**
   * Pair the unpaired handle groups that are each other's mirror image (mirrorImage: after the groups were rebuilt
   * from the server's constraints, an undo or a file without pairs).
   */
  repair() {
    const mirrorOf = this.result?.mirrorOf;
    const s = this.selection;
    if (!mirrorOf || s.groups.length < 2) return;
    const lists = s.groups.map((_, g) => s.groupIndices(g));
    const keys = lists.map((l) => l.join(','));
    lists.forEach((list, g) => {
      if (!list.length || s.partnerOf(g) >= 0) return;
      const image = mirrorImage(mirrorOf, list).join(',');
      const h = keys.indexOf(image);
      if (h >= 0 && h !== g && s.partnerOf(h) < 0) s.pair(g, h);
    });
  }

  /** The partner of each client group (-1: none), as autosaved. */
  partners() {
    return this.selection.groups.map((_, g) => this.selection.partnerOf(g));
  }

  /**
   * Pair client groups again from partners() as saved.
   * @param {number[]|null|undefined} partners
   */
  setPartners(partners) {
    const s = this.selection;
    (partners || []).forEach((h, g) => {
      if (Number.isInteger(h) && h >= 0 && h < s.groups.length && g < s.groups.length && h !== g) s.pair(g, h);
    });
  }

  /**
   * A constraints document with the pairs of its handle_groups (server group k = client group groupMap[k]).
   * @param {{[key: string]: any}} doc the server's document (JSON)
   * @param {number[]} groupMap
   */
  documentWithPartners(doc, groupMap) {
    /** @type {[number, number][]} */
    const pairs = [];
    groupMap.forEach((g, k) => {
      const l = groupMap.indexOf(this.selection.partnerOf(g));
      if (l > k) pairs.push([k, l]);
    });
    if (!pairs.length) return doc;
    return { ...doc, meta: { ...(doc.meta || {}), [PARTNERS_KEY]: pairs } };
  }

  /**
   * Pair client groups from a document's [[k, l], ...] (its handle_groups k and l are client groups k and l).
   * @param {[number, number][]|null|undefined} pairs
   */
  setPairs(pairs) {
    const n = this.selection.groups.length;
    for (const [k, l] of pairs || []) if (k < n && l < n && k !== l) this.selection.pair(k, l);
  }
}
