// The keyframe model of the timeline (timeline.js): a keyframe holds one column-major 4×4 per handle group of the
// server's constraint set, and between keyframes the groups move as arap.constraints.keyframes says (the command
// line's `arap animate` renders the same animation from the saved constraints document): each group turns about its
// pivot (the centroid of its vertices in the constraint set's pose) by the spherical linear interpolation of the two
// rotations of the polar decompositions, while the stretch parts blend linearly and the pivot's image moves on a
// straight line. This is pure arithmetic, kept apart from the time bar so that it can be checked against the
// Python side on its own.
import * as THREE from 'three';

/**
 * @typedef {{ms: number, transforms: number[][], easing?: string, id?: number, shape?: Float32Array|null}} Keyframe
 *   time in milliseconds, one column-major 4×4 (16 numbers) per group of the server's constraint set (handle groups,
 *   then point handles), how the groups move to the next keyframe (one of EASINGS; absent: linear), the number
 *   under which the server kept the shape shown when the keyframe was made (keep_shape), and that shape as the page
 *   last saw it (x, y, z per vertex), given back to a new session after a restore or a lost connection
 */

/** The easings of a keyframe, in the order of export_animation's `easings` numbers (as arap.constraints.keyframes). */
export const EASINGS = ['linear', 'ease-in-out', 'ease-in', 'ease-out'];

/**
 * The fraction of the way at the fraction `s` of the time between two keyframes (arap.constraints.keyframes.ease).
 * @param {string|undefined} easing
 * @param {number} s
 */
export function ease(easing, s) {
  if (easing === 'ease-in-out') return s * s * (3 - 2 * s);
  if (easing === 'ease-in') return s * s;
  if (easing === 'ease-out') return 1 - (1 - s) * (1 - s);
  return s;
}

// ------------------------------------------------------------------ 3×3 algebra (row-major arrays of 9)

/**
 * @param {number[]} a
 * @param {number[]} b
 * @returns {number[]} a · b
 */
function mul3(a, b) {
  /** @type {number[]} */
  const out = new Array(9);
  for (let r = 0; r < 3; r++) {
    for (let c = 0; c < 3; c++) out[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
  }
  return out;
}

/**
 * @param {number[]} a
 * @returns {number[]}
 */
function transpose3(a) {
  return [a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8]];
}

/**
 * @param {number[]} a
 * @returns {number[]}
 */
function inverse3(a) {
  const [m00, m01, m02, m10, m11, m12, m20, m21, m22] = a;
  const c00 = m11 * m22 - m12 * m21;
  const c01 = m12 * m20 - m10 * m22;
  const c02 = m10 * m21 - m11 * m20;
  const det = m00 * c00 + m01 * c01 + m02 * c02;
  return [
    c00 / det, (m02 * m21 - m01 * m22) / det, (m01 * m12 - m02 * m11) / det,
    c01 / det, (m00 * m22 - m02 * m20) / det, (m02 * m10 - m00 * m12) / det,
    c02 / det, (m01 * m20 - m00 * m21) / det, (m00 * m11 - m01 * m10) / det,
  ];
}

/**
 * Polar decomposition A = R S (R a rotation, S symmetric positive definite) of a 3×3 with a positive determinant,
 * by Newton's iteration R ← (R + R⁻ᵀ) / 2 (the factor scipy.linalg.polar gives).
 * @param {number[]} A row-major
 * @returns {{R: number[], S: number[]}}
 */
export function polar(A) {
  let R = A.slice();
  for (let k = 0; k < 100; k++) {
    const inv = transpose3(inverse3(R));
    const next = R.map((x, i) => 0.5 * (x + inv[i]));
    let change = 0;
    for (let i = 0; i < 9; i++) change = Math.max(change, Math.abs(next[i] - R[i]));
    R = next;
    if (change <= 1e-15) break;
  }
  const S = mul3(transpose3(R), A);
  return { R, S: S.map((x, i) => 0.5 * (x + S[3 * (i % 3) + Math.floor(i / 3)])) };
}

/**
 * Row-major 3×3 part and translation of a column-major 4×4.
 * @param {number[]} e
 * @returns {{A: number[], t: number[]}}
 */
function split(e) {
  return { A: [e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10]], t: [e[12], e[13], e[14]] };
}

/**
 * @param {number[]} A row-major 3×3
 * @param {number[]} p
 * @returns {number[]} A p
 */
function apply3(A, p) {
  return [0, 1, 2].map((r) => A[3 * r] * p[0] + A[3 * r + 1] * p[1] + A[3 * r + 2] * p[2]);
}

const _m4 = new THREE.Matrix4();
/** @param {number[]} R a row-major rotation */
function quaternionOf(R) {
  _m4.set(R[0], R[1], R[2], 0, R[3], R[4], R[5], 0, R[6], R[7], R[8], 0, 0, 0, 0, 1);
  return new THREE.Quaternion().setFromRotationMatrix(_m4);
}

/**
 * @param {THREE.Quaternion} q
 * @returns {number[]} row-major
 */
function rotationOf(q) {
  const e = _m4.makeRotationFromQuaternion(q).elements;
  return [e[0], e[4], e[8], e[1], e[5], e[9], e[2], e[6], e[10]];
}

/**
 * The transform between two keyframe transforms `a` and `b` (column-major 4×4) at `s` in [0, 1] for a group turning
 * about `pivot`: as arap.constraints.keyframes.Keyframes.handle_targets (rotation by slerp, stretch and pivot linearly).
 * @param {number[]} a @param {number[]} b @param {number} s @param {number[]} pivot
 * @returns {number[]} column-major 4×4
 */
export function turn(a, b, s, pivot) {
  const A = split(a);
  const B = split(b);
  const pa = polar(A.A);
  const pb = polar(B.A);
  const q = quaternionOf(pa.R).slerp(quaternionOf(pb.R), s);
  const M = mul3(rotationOf(q), pa.S.map((x, i) => (1 - s) * x + s * pb.S[i]));
  const ca = apply3(A.A, pivot).map((x, i) => x + A.t[i]);
  const cb = apply3(B.A, pivot).map((x, i) => x + B.t[i]);
  const centre = ca.map((x, i) => (1 - s) * x + s * cb[i]);
  const mp = apply3(M, pivot);
  const t = centre.map((x, i) => x - mp[i]);
  return [M[0], M[3], M[6], 0, M[1], M[4], M[7], 0, M[2], M[5], M[8], 0, t[0], t[1], t[2], 1];
}

/**
 * The groups' transforms at `seconds`: the first keyframe's before it, the last's after it, in between the turn of
 * each group about its pivot (see `turn`; a point handle's pivot is the point, which so moves on a straight line), at
 * the pace of the earlier keyframe's easing.
 * @param {Keyframe[]} keys in increasing time
 * @param {number[][]} pivots per group
 * @param {number} seconds
 * @returns {number[][]}
 */
export function interpolate(keys, pivots, seconds) {
  if (!keys.length) return [];
  if (seconds <= keys[0].ms / 1000) return keys[0].transforms.map((m) => m.slice());
  const last = keys[keys.length - 1];
  if (seconds >= last.ms / 1000) return last.transforms.map((m) => m.slice());
  let b = 1;
  while (keys[b].ms / 1000 <= seconds) b++;
  const ka = keys[b - 1];
  const kb = keys[b];
  const ta = ka.ms / 1000;
  const s = ease(ka.easing, (seconds - ta) / (kb.ms / 1000 - ta));
  return ka.transforms.map((m, g) => turn(m, kb.transforms[g], s, pivots[g]));
}

/**
 * `m` · `c`⁻¹ (column-major 4×4s).
 * @param {number[]} m @param {number[]} c
 * @returns {number[]}
 */
export function rebased(m, c) {
  return Array.from(new THREE.Matrix4().fromArray(m).multiply(new THREE.Matrix4().fromArray(c).invert()).elements);
}

/**
 * Frames an export of `keys` at `fps` solves: as arap.animation.frame_times.
 * @param {Keyframe[]} keys
 * @param {number} fps
 */
export function frameCount(keys, fps) {
  if (!keys.length) return 0;
  const span = (keys[keys.length - 1].ms - keys[0].ms) / 1000;
  const count = Math.floor(span * fps + 1e-9) + 1;
  return (count - 1) / fps < span - 1e-9 / fps ? count + 1 : count;
}
