// Transform arithmetic of the handle gizmo: the angle the pointer sweeps around a point on screen, snapping, the
// grid step of a model, and rigid transforms about a pivot (THREE.Matrix4 elements are doubles: exact enough).
import * as THREE from 'three';

/** Rotations snap to multiples of this many degrees. */
export const ROTATION_SNAP_DEG = 15;

/**
 * Signed angle (radians, in (-π, π]) from screen point `a` to screen point `b` around `centre`, counter-clockwise
 * as seen on screen positive. Points are CSS pixels [x, y] with y down, as pointer events give them; 0 when
 * either point is on the centre.
 * @param {number[]} centre
 * @param {number[]} a
 * @param {number[]} b
 */
export function sweptAngle(centre, a, b) {
  const ax = a[0] - centre[0];
  const ay = centre[1] - a[1];
  const bx = b[0] - centre[0];
  const by = centre[1] - b[1];
  if ((ax === 0 && ay === 0) || (bx === 0 && by === 0)) return 0;
  return Math.atan2(ax * by - ay * bx, ax * bx + ay * by);
}

/**
 * `value` rounded to a multiple of `step` (unchanged when the step is not positive).
 * @param {number} value
 * @param {number} step
 */
export function snapTo(value, step) {
  if (!(step > 0)) return value;
  const s = Math.round(value / step) * step;
  return s === 0 ? 0 : s; // no -0
}

/**
 * The 1-2-5 value (…, 0.01, 0.02, 0.05, 0.1, …) nearest to `x` on a log scale; 0 for x ≤ 0 or not finite.
 * @param {number} x
 */
export function niceStep(x) {
  if (!(x > 0) || !Number.isFinite(x)) return 0;
  const e = Math.floor(Math.log10(x));
  const base = 10 ** e;
  const m = x / base;
  // boundaries halfway (geometrically) between 1, 2, 5 and 10
  const pick = m < Math.SQRT2 ? 1 : m < Math.sqrt(10) ? 2 : m < Math.sqrt(50) ? 5 : 10;
  return Number((pick * base).toPrecision(12));
}

/**
 * Translation grid step of a model: 1/100 of its bounding-box diagonal, as a 1-2-5 value.
 * @param {THREE.Box3|null} box
 */
export function gridStep(box) {
  return box ? niceStep(box.min.distanceTo(box.max) / 100) : 0;
}

/**
 * The rigid transform rotating by `angle` radians about the line through `pivot` along `axis` (unit vector),
 * applied after `previous`: T(p) · R · T(−p) · previous.
 * @param {THREE.Vector3} pivot @param {THREE.Vector3} axis @param {number} angle
 * @param {THREE.Matrix4} [previous] @returns {THREE.Matrix4}
 */
export function rotationAbout(pivot, axis, angle, previous) {
  const c = Math.cos(angle);
  const s = Math.sin(angle);
  const t = 1 - c;
  const { x, y, z } = axis;
  // R by Rodrigues' formula, exact for multiples of 90° up to cos/sin rounding
  const r = [
    t * x * x + c, t * x * y - s * z, t * x * z + s * y,
    t * x * y + s * z, t * y * y + c, t * y * z - s * x,
    t * x * z - s * y, t * y * z + s * x, t * z * z + c,
  ];
  const p = pivot;
  const tx = p.x - (r[0] * p.x + r[1] * p.y + r[2] * p.z);
  const ty = p.y - (r[3] * p.x + r[4] * p.y + r[5] * p.z);
  const tz = p.z - (r[6] * p.x + r[7] * p.y + r[8] * p.z);
  const m = new THREE.Matrix4().set(r[0], r[1], r[2], tx, r[3], r[4], r[5], ty, r[6], r[7], r[8], tz, 0, 0, 0, 1);
  return previous ? m.multiply(previous) : m;
}

/**
 * The translation by `offset` applied after `previous`.
 * @param {THREE.Vector3} offset
 * @param {THREE.Matrix4} [previous]
 * @returns {THREE.Matrix4}
 */
export function translationBy(offset, previous) {
  const m = new THREE.Matrix4().makeTranslation(offset.x, offset.y, offset.z);
  return previous ? m.multiply(previous) : m;
}

/**
 * The rotation part of a rigid transform as a quaternion.
 * @param {THREE.Matrix4} matrix
 */
export function rotationOf(matrix) {
  const q = new THREE.Quaternion();
  matrix.decompose(new THREE.Vector3(), q, new THREE.Vector3());
  return q;
}
