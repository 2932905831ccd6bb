// Mirror symmetry of a mesh: the plane (the best of the coordinate and principal planes, refined by moving it until
// the mirrored surface lies closest to the surface; or an axis plane through the bounding-box centre) and the vertex
// correspondence across it: each vertex's partner is the vertex nearest to where its reflection meets the surface,
// when the reflection lies within a tolerance of the surface. Scans that are only nearly symmetric, with triangles
// that do not mirror each other, pair as well as exact models. k-d trees keep it O(n log n). No DOM, no
// Three.js: usable from Node as well. The nearest-point queries it is built on are in nearest.js.
import { PointTree, Surface } from './nearest.js';

/** Share of the vertices that must have a mirror partner for the shape to count as symmetric. */
export const MIN_MATCHED = 0.8;
/** Default distance (a fraction of the bounding-box diagonal) by which a reflection may miss the surface. */
export const DEFAULT_TOLERANCE = 0.015;
/** Range of that distance offered to the user (fractions of the diagonal). */
export const TOLERANCE_RANGE = { min: 0.001, max: 0.1 };
/** Vertices scored per candidate plane, and used to refine it, before the best one is matched in full. */
const SAMPLE = 2000;
/** Refinement steps of a candidate plane (each re-pairs the sample and fits the plane to the pairs). */
const REFINE_STEPS = 12;
/** Vertices the coarse refinement steps pair the sample with. */
const FAR_TARGETS = 4000;
/** Candidate planes whose normals' cosine is above this (about 1.5°) are one candidate. */
const SAME_NORMAL = 0.9997;
export const AXES = ['x', 'y', 'z'];

/** A plane: a unit normal whose largest component is positive, and a point on it. @typedef {{normal: number[], point: number[]}} Plane */

/**
 * Bounding box, diagonal, centroid and covariance of float positions (3 per vertex).
 * @param {ArrayLike<number>} pos
 */
function moments(pos) {
  const n = pos.length / 3;
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  const mean = [0, 0, 0];
  for (let i = 0; i < n; i++) {
    for (let k = 0; k < 3; k++) {
      const v = pos[3 * i + k];
      mean[k] += v;
      if (v < lo[k]) lo[k] = v;
      if (v > hi[k]) hi[k] = v;
    }
  }
  for (let k = 0; k < 3; k++) mean[k] /= Math.max(1, n);
  const cov = [0, 0, 0, 0, 0, 0, 0, 0, 0];
  for (let i = 0; i < n; i++) {
    const d0 = pos[3 * i] - mean[0];
    const d1 = pos[3 * i + 1] - mean[1];
    const d2 = pos[3 * i + 2] - mean[2];
    cov[0] += d0 * d0;
    cov[1] += d0 * d1;
    cov[2] += d0 * d2;
    cov[4] += d1 * d1;
    cov[5] += d1 * d2;
    cov[8] += d2 * d2;
  }
  cov[3] = cov[1];
  cov[6] = cov[2];
  cov[7] = cov[5];
  const diag = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  const centre = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
  return { n, lo, hi, diag, mean, centre, cov };
}

/**
 * Eigenvectors (columns of the returned row-major 3×3) of a symmetric 3×3 matrix, by Jacobi rotations.
 * @param {number[]} m row-major, 9 numbers
 * @returns {number[][]}
 */
export function eigenvectors3(m) {
  const a = m.slice();
  const v = [1, 0, 0, 0, 1, 0, 0, 0, 1];
  for (let sweep = 0; sweep < 50; sweep++) {
    const off = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
    if (off < 1e-30 * (a[0] * a[0] + a[4] * a[4] + a[8] * a[8]) || off === 0) break;
    for (const [p, q] of [[0, 1], [0, 2], [1, 2]]) {
      const apq = a[3 * p + q];
      if (apq === 0) continue;
      const theta = (a[3 * q + q] - a[3 * p + p]) / (2 * apq);
      const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
      const c = 1 / Math.sqrt(t * t + 1);
      const s = t * c;
      for (let k = 0; k < 3; k++) {
        // A ← Jᵀ A J, V ← V J
        const akp = a[3 * k + p];
        const akq = a[3 * k + q];
        a[3 * k + p] = c * akp - s * akq;
        a[3 * k + q] = s * akp + c * akq;
      }
      for (let k = 0; k < 3; k++) {
        const apk = a[3 * p + k];
        const aqk = a[3 * q + k];
        a[3 * p + k] = c * apk - s * aqk;
        a[3 * q + k] = s * apk + c * aqk;
      }
      for (let k = 0; k < 3; k++) {
        const vkp = v[3 * k + p];
        const vkq = v[3 * k + q];
        v[3 * k + p] = c * vkp - s * vkq;
        v[3 * k + q] = s * vkp + c * vkq;
      }
    }
  }
  return [0, 1, 2].map((j) => [v[j], v[3 + j], v[6 + j]]);
}

/**
 * A plane {normal, point} with a unit normal whose largest component is positive.
 * @param {number[]} normal
 * @param {number[]} point
 * @returns {Plane}
 */
function plane(normal, point) {
  const len = Math.hypot(normal[0], normal[1], normal[2]);
  let nrm = normal.map((c) => c / len);
  const big = nrm.reduce((b, c, k) => (Math.abs(c) > Math.abs(nrm[b]) ? k : b), 0);
  if (nrm[big] < 0) nrm = nrm.map((c) => -c);
  // a normal within a hair of a coordinate axis is that axis exactly (models are usually built on one)
  if (1 - Math.abs(nrm[big]) < 1e-9) nrm = [0, 1, 2].map((k) => (k === big ? 1 : 0));
  return { normal: nrm, point: point.slice() };
}

/**
 * The reflection about a plane as a column-major 4×4 (Three.js Matrix4 element order).
 * @param {{normal: number[], point: number[]}} pl unit normal and a point of the plane
 */
export function reflectionMatrix(pl) {
  const [a, b, c] = pl.normal;
  const { point } = pl;
  const d = 2 * (a * point[0] + b * point[1] + c * point[2]);
  return [
    1 - 2 * a * a, -2 * a * b, -2 * a * c, 0,
    -2 * a * b, 1 - 2 * b * b, -2 * b * c, 0,
    -2 * a * c, -2 * b * c, 1 - 2 * c * c, 0,
    d * a, d * b, d * c, 1,
  ];
}

/**
 * About `count` of the vertices 0..n-1, evenly spread over the numbering.
 * @param {number} n
 * @param {number} count
 */
function spread(n, count) {
  const stride = Math.max(1, Math.floor(n / count));
  /** @type {number[]} */
  const out = [];
  for (let i = 0; i < n; i += stride) out.push(i);
  return out;
}

/**
 * Reflection of (x, y, z) about a plane, into `out`.
 * @param {Plane} pl
 * @param {number} x
 * @param {number} y
 * @param {number} z
 * @param {number[]} out
 */
function reflectPoint(pl, x, y, z, out) {
  const [a, b, c] = pl.normal;
  const s = 2 * (a * (x - pl.point[0]) + b * (y - pl.point[1]) + c * (z - pl.point[2]));
  out[0] = x - s * a;
  out[1] = y - s * b;
  out[2] = z - s * c;
}

/**
 * Pair the vertices `which` (all when null) across a plane: for each, the vertex nearest to where the surface comes
 * closest to its reflection, when that is within `tol` (else -1); and the closest points themselves (3 per vertex).
 * @param {ArrayLike<number>} pos
 * @param {Surface|PointTree} surface what the reflections are measured to
 * @param {Plane} pl
 * @param {number} tol
 * @param {number[]|null} [which]
 */
function pairAcross(pos, surface, pl, tol, which = null) {
  const count = which ? which.length : pos.length / 3;
  const partner = new Int32Array(count);
  const points = new Float64Array(3 * count);
  const r = [0, 0, 0];
  let matched = 0;
  for (let k = 0; k < count; k++) {
    const i = which ? which[k] : k;
    reflectPoint(pl, pos[3 * i], pos[3 * i + 1], pos[3 * i + 2], r);
    const j = surface.closest(r[0], r[1], r[2], tol);
    partner[k] = j;
    if (j >= 0) {
      matched++;
      points[3 * k] = surface.point[0];
      points[3 * k + 1] = surface.point[1];
      points[3 * k + 2] = surface.point[2];
    }
  }
  return { partner, points, matched };
}

/**
 * The plane that best maps the vertices `which[k]` onto the surface points `points[k]` paired with them: its normal
 * the dominant direction of their differences, through the mean of their midpoints. `pl` when there are none.
 * @param {ArrayLike<number>} pos
 * @param {Plane} pl
 * @param {number[]|null} which
 * @param {Int32Array} partner
 * @param {Float64Array} points
 * @returns {Plane}
 */
function fitPlane(pos, pl, which, partner, points) {
  const cov = [0, 0, 0, 0, 0, 0, 0, 0, 0];
  const mid = [0, 0, 0];
  let m = 0;
  for (let k = 0; k < partner.length; k++) {
    if (partner[k] < 0) continue;
    const i = which ? which[k] : k;
    const d = [0, 1, 2].map((t) => pos[3 * i + t] - points[3 * k + t]);
    for (let a = 0; a < 3; a++) {
      mid[a] += (pos[3 * i + a] + points[3 * k + a]) / 2;
      for (let b = 0; b < 3; b++) cov[3 * a + b] += d[a] * d[b];
    }
    m++;
  }
  if (m < 3) return pl;
  let normal = null;
  let top = 0;
  for (const v of eigenvectors3(cov)) {
    const cv = [0, 1, 2].map((a) => cov[3 * a] * v[0] + cov[3 * a + 1] * v[1] + cov[3 * a + 2] * v[2]);
    const q = v[0] * cv[0] + v[1] * cv[1] + v[2] * cv[2];
    if (q > top) {
      top = q;
      normal = v;
    }
  }
  if (!normal) return pl;
  const fitted = plane(normal, mid.map((v) => v / m));
  // a fitted plane whose normal is the old one to rounding keeps it exactly (an axis plane stays one)
  const cos = Math.abs(fitted.normal[0] * pl.normal[0] + fitted.normal[1] * pl.normal[1] + fitted.normal[2] * pl.normal[2]);
  return 1 - cos < 1e-14 ? { normal: pl.normal.slice(), point: fitted.point } : fitted;
}

/**
 * Move plane `pl` until the sample's reflections lie closest to the surface: pair, fit the plane to the pairs, and
 * again, with a search radius shrinking from `far` to `tol`.
 * @param {ArrayLike<number>} pos
 * @param {{grid: PointTree, radius: number}} far
 * @param {Surface} near
 * @param {Plane} pl
 * @param {number[]} sample
 * @param {number} tol
 */
function refine(pos, far, near, pl, sample, tol) {
  let current = pl;
  for (let step = 0; step < REFINE_STEPS; step++) {
    const coarse = step < REFINE_STEPS / 2;
    const r = coarse ? Math.max(tol, far.radius * 0.7 ** step) : tol;
    const { partner, points } = pairAcross(pos, coarse ? far.grid : near, current, r, sample);
    const next = fitPlane(pos, current, sample, partner, points);
    const moved = Math.abs(1 - Math.abs(next.normal.reduce((s, c, k) => s + c * current.normal[k], 0)))
      + Math.abs(next.normal.reduce((s, c, k) => s + c * (next.point[k] - current.point[k]), 0)) / far.radius;
    current = next;
    if (!coarse && moved < 1e-12) break;
  }
  return current;
}

/**
 * Find the mirror symmetry of a mesh.
 * @param {ArrayLike<number>} pos vertex positions, 3 per vertex
 * @param {ArrayLike<number>|null} faces triangle indices (the surface the reflections are measured to; without them
 *   the vertices)
 * @param {string} axis 'auto' (the best of the coordinate and principal planes through the centroid, refined), or
 *   'x', 'y' or 'z' (that axis's plane through the bounding-box centre, however well it matches)
 * @param {number} tolerance how far (a fraction of the bounding-box diagonal) a vertex's reflection may lie from
 *   the surface for the vertex to have a partner
 * @returns {{plane: {normal: number[], point: number[]}|null, mirrorOf: Int32Array|null, matched: number,
 *   tolerance: number, work: number, ms: number}} `plane` null when no plane pairs MIN_MATCHED of the vertices
 *   (auto); `mirrorOf` each vertex's partner (-1: none; not always mutual where the two sides' triangles differ),
 *   `matched` the share of vertices with a partner, `tolerance` that distance in model units, `work` the distances
 *   computed by the nearest-point queries (a measure of the time that does not depend on the machine)
 */
export function detectSymmetry(pos, faces, axis = 'auto', tolerance = DEFAULT_TOLERANCE) {
  const t0 = performance.now();
  const mo = moments(pos);
  const { n, diag } = mo;
  const none = { plane: null, mirrorOf: null, matched: 0, tolerance: 0, work: 0, ms: 0 };
  if (n === 0 || !(diag > 0)) return { ...none, ms: performance.now() - t0 };
  const frac = Math.min(TOLERANCE_RANGE.max, Math.max(TOLERANCE_RANGE.min, Number(tolerance) || DEFAULT_TOLERANCE));
  const tol = frac * diag;
  const near = new Surface(pos, faces, tol);
  const unit = (/** @type {number} */ k) => [0, 1, 2].map((t) => (t === k ? 1 : 0));
  const fixedAxis = AXES.indexOf(axis);
  let pl;
  /** @type {PointTree|null} */
  let farTree = null;
  if (fixedAxis >= 0) pl = plane(unit(fixedAxis), mo.centre);
  else {
    const sample = spread(n, SAMPLE);
    // the coarse steps search further, among fewer vertices (a plane off by a few degrees misses the surface)
    const radius = Math.max(2 * tol, 0.08 * diag);
    farTree = new PointTree(pos, spread(n, FAR_TARGETS));
    const far = { grid: farTree, radius };
    /** @type {Plane[]} */
    const candidates = [];
    for (const nrm of [...[0, 1, 2].map(unit), ...eigenvectors3(mo.cov)]) {
      // a principal axis within a degree or so of a coordinate axis refines to the same plane: refined once
      const cand = plane(nrm, mo.mean);
      if (!candidates.some((c) => Math.abs(c.normal.reduce((sum, v, k) => sum + v * cand.normal[k], 0)) > SAME_NORMAL)) {
        candidates.push(cand);
      }
    }
    const score = (/** @type {Plane} */ cand) => pairAcross(pos, near, cand, tol, sample).matched;
    // every candidate refined (six short runs on the sample), the one that pairs most of the sample kept
    let bestScore = -1;
    let best = candidates[0]; // replaced by the first candidate's own best (a score is at least 0)
    for (const cand of candidates) {
      const start = score(cand);
      const refined = refine(pos, far, near, cand, sample, tol);
      const s = score(refined);
      /** @type {[Plane, number]} */
      const [better, sc] = s >= start ? [refined, s] : [cand, start];
      if (sc > bestScore) {
        bestScore = sc;
        best = better;
      }
    }
    pl = best;
  }
  const { partner: mirrorOf, matched } = pairAcross(pos, near, pl, tol);
  const work = near.tree.visits + (farTree ? farTree.visits : 0);
  const found = { plane: pl, mirrorOf, matched: matched / n, tolerance: tol, work, ms: 0 };
  if (fixedAxis < 0 && found.matched < MIN_MATCHED) return { ...none, matched: found.matched, tolerance: tol, work,
    ms: performance.now() - t0 };
  return { ...found, ms: performance.now() - t0 };
}

/**
 * The mirror image of a vertex set under a correspondence: the partners of its vertices, and the vertices whose
 * partner is in it (so that a region pairs with all of its image where the two sides are meshed differently).
 * @param {Int32Array} mirrorOf detectSymmetry's correspondence
 * @param {Iterable<number>} indices
 * @returns {number[]} ascending
 */
export function mirrorImage(mirrorOf, indices) {
  const inSet = new Uint8Array(mirrorOf.length);
  for (const i of indices) inSet[i] = 1;
  const out = new Uint8Array(mirrorOf.length);
  for (let j = 0; j < mirrorOf.length; j++) {
    if (inSet[j] && mirrorOf[j] >= 0) out[mirrorOf[j]] = 1;
    if (mirrorOf[j] >= 0 && inSet[mirrorOf[j]]) out[j] = 1;
  }
  const list = [];
  for (let j = 0; j < out.length; j++) if (out[j]) list.push(j);
  return list;
}
