// Point handles: placed by a click on the surface (a triangle and barycentric coordinates from the raycast hit),
// drawn as small spheres that follow the deformed surface, removed by a click with the subtract modifier.
import * as THREE from 'three';
import { NONE } from './selection.js';
import { groupColor } from './rolecolors.js';

/** Marker radius, as a share of the mesh's bounding-box diagonal. */
const MARKER_SIZE = 0.012;

/**
 * The point handle of a raycast hit on the mesh: its triangle and barycentric coordinates (corners in the order of
 * the triangle's indices; non-negative, summing to 1).
 * @param {{faceIndex?: number|null, point: THREE.Vector3}} hit
 * @param {ArrayLike<number>} positions
 * @param {ArrayLike<number>} faces
 * @returns {{face: number, barycentric: number[]}|null}
 */
export function pointFromHit(hit, positions, faces) {
  const f = hit.faceIndex;
  if (f === null || f === undefined || 3 * f + 2 >= faces.length) return null;
  const corner = (/** @type {number} */ k) => {
    const i = faces[3 * f + k];
    return new THREE.Vector3(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
  };
  const b = new THREE.Triangle(corner(0), corner(1), corner(2)).getBarycoord(hit.point, new THREE.Vector3());
  if (!b) return null;
  const raw = [b.x, b.y, b.z].map((x) => Math.max(0, x));
  const sum = raw[0] + raw[1] + raw[2];
  if (!(sum > 0)) return null;
  const barycentric = raw.map((x) => x / sum);
  barycentric[2] = Math.max(0, 1 - barycentric[0] - barycentric[1]); // the sum is 1 up to one rounding
  return { face: f, barycentric };
}

/**
 * Where a point handle lies on the surface `positions`.
 * @param {{face: number, barycentric: number[]}} point
 * @param {ArrayLike<number>} positions
 * @param {ArrayLike<number>} faces
 * @returns {number[]} x, y, z
 */
export function pointPosition(point, positions, faces) {
  const out = [0, 0, 0];
  for (let k = 0; k < 3; k++) {
    const i = faces[3 * point.face + k];
    const w = point.barycentric[k];
    for (let d = 0; d < 3; d++) out[d] += w * positions[3 * i + d];
  }
  return out;
}

export class PointHandles {
  /**
   * @param {object} opts
   * @param {import('./viewer.js').Viewer} opts.viewer
   * @param {import('./selection.js').Selection} opts.selection
   * @param {() => void} opts.changed the selection was edited: redraw and send it
   * @param {() => number|null} opts.weight the weight of new handles, null for hard ones
   */
  constructor({ viewer, selection, changed, weight }) {
    this.viewer = viewer;
    this.selection = selection;
    this.changed = changed;
    this.weight = weight;
    this.group = new THREE.Group();
    viewer.scene.add(this.group);
    this.sphere = new THREE.SphereGeometry(1, 16, 12);
    /** @type {THREE.Mesh[]} */
    this.markers = [];
  }

  get faces() {
    // a geometry of the viewer always has its triangles (viewer.js setMesh)
    return this.viewer.geometry ? /** @type {THREE.BufferAttribute} */ (this.viewer.geometry.index).array : new Uint32Array(0);
  }

  /**
   * A click on the surface in point mode: add a handle there, or (subtract) remove the nearest one.
   * @param {{faceIndex?: number|null, point: THREE.Vector3}} hit
   * @param {boolean} subtract
   */
  pick(hit, subtract) {
    const point = pointFromHit(hit, this.viewer.positions, this.faces);
    if (!point) return;
    if (subtract) {
      const g = this.nearest(hit.point);
      if (g < 0) return;
      this.selection.removeGroup(g);
    } else {
      this.selection.addPoint({ ...point, weight: this.weight() });
    }
    this.changed();
  }

  /**
   * The point groups that cannot move: every corner of their triangle is an anchor, a handle or (with a region of
   * interest) outside it. The server refuses a constraint set holding such a point.
   */
  stuck() {
    const { roi, role } = this.selection;
    const withRoi = this.selection.roiCount > 0;
    const faces = this.faces;
    const free = (/** @type {number} */ i) => role[i] === NONE && (!withRoi || roi[i] === 1);
    /** @type {number[]} */
    const out = [];
    this.selection.groups.forEach((g, k) => {
      if (!g.point) return;
      const f = g.point.face;
      if (!free(faces[3 * f]) && !free(faces[3 * f + 1]) && !free(faces[3 * f + 2])) out.push(k);
    });
    return out;
  }

  /**
   * The point group nearest to a world position, within a few marker sizes (or -1).
   * @param {THREE.Vector3} p
   */
  nearest(p) {
    let best = -1;
    let bestD = (4 * this.markerRadius()) ** 2;
    this.selection.groups.forEach((g, k) => {
      if (!g.point) return;
      const q = pointPosition(g.point, this.viewer.positions, this.faces);
      const d = (q[0] - p.x) ** 2 + (q[1] - p.y) ** 2 + (q[2] - p.z) ** 2;
      if (d < bestD) {
        bestD = d;
        best = k;
      }
    });
    return best;
  }

  markerRadius() {
    const box = this.viewer.geometry?.boundingBox;
    return box ? MARKER_SIZE * box.min.distanceTo(box.max) : 0.01;
  }

  /**
   * What the gizmo of group g attaches to: its vertices, or a point's triangle corners and weights.
   * @param {number} g
   * @returns {{indices: number[], weights: number[]|null}}
   */
  anchor(g) {
    const group = this.selection.groups[g];
    if (!group?.point) return { indices: this.selection.groupIndices(g), weights: null };
    const f = group.point.face;
    const faces = this.faces;
    return { indices: [faces[3 * f], faces[3 * f + 1], faces[3 * f + 2]], weights: group.point.barycentric };
  }

  /** Markers for the current point groups (after the selection changed). */
  rebuild() {
    for (const m of this.markers) {
      this.group.remove(m);
      /** @type {THREE.Material} */ (m.material).dispose();
    }
    this.markers = [];
    this.selection.groups.forEach((g, k) => {
      if (!g.point) return;
      const material = new THREE.MeshStandardMaterial({ color: new THREE.Color(...groupColor(k)), roughness: 0.4 });
      const m = new THREE.Mesh(this.sphere, material);
      m.userData.group = k;
      this.markers.push(m);
      this.group.add(m);
    });
    this.refresh();
  }

  /** Put the markers on the current surface. */
  refresh() {
    const r = this.markerRadius();
    for (const m of this.markers) {
      const k = m.userData.group;
      const g = this.selection.groups[k];
      if (!g?.point) continue;
      m.position.fromArray(pointPosition(g.point, this.viewer.positions, this.faces));
      m.scale.setScalar(k === this.selection.activeGroup ? 1.35 * r : r);
    }
    this.viewer.requestRender();
  }

  /** Screen positions (canvas CSS pixels) of the point groups, by client group (null for vertex groups). */
  screen() {
    return this.selection.groups.map((g) => (g.point
      ? this.viewer.project(pointPosition(g.point, this.viewer.positions, this.faces)) : null));
  }
}
