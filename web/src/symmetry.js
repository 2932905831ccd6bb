// Mirror symmetry of a vertex set: the plane (found among the bounding-box and principal axes through the
// centroid, or given as an axis through the bounding-box centre) and the vertex correspondence across it, by
// nearest neighbours through a uniform grid hash (O(n)). No DOM, no Three.js: usable from Node as well.

/** Share of the vertices that must have a mirror partner for the shape to count as symmetric. */
export const MIN_MATCHED = 0.9;
/** Tolerance of an exact match, a fraction of the bounding-box diagonal. */
export const EXACT_TOLERANCE = 1e-3;
/** Vertices scored per candidate plane before the best one is matched in full. */
const SAMPLE = 3000;
export const AXES = ['x', 'y', 'z'];

/** Bounding box, diagonal, centroid and covariance of float positions (3 per vertex). */
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

/** Eigenvectors (columns of the returned row-major 3×3) of a symmetric 3×3 matrix, by Jacobi rotations. */
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

/** A plane {normal, point} with a unit normal whose largest component is positive. */
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

/** A uniform grid of cell size `cell`, hashed into buckets: nearest neighbour within `cell` / 2 in O(1). */
class GridHash {
  constructor(pos, cell) {
    const n = pos.length / 3;
    this.pos = pos;
    this.inv = 1 / cell;
    let size = 1;
    while (size < 2 * n) size <<= 1;
    this.mask = size - 1;
    this.head = new Int32Array(size).fill(-1);
    this.next = new Int32Array(n);
    for (let i = 0; i < n; i++) {
      const h = this._bucket(
        Math.floor(pos[3 * i] * this.inv), Math.floor(pos[3 * i + 1] * this.inv), Math.floor(pos[3 * i + 2] * this.inv));
      this.next[i] = this.head[h];
      this.head[h] = i;
    }
  }

  _bucket(ix, iy, iz) {
    return (Math.imul(ix, 73856093) ^ Math.imul(iy, 19349663) ^ Math.imul(iz, 83492791)) & this.mask;
  }

  /**
   * The vertex nearest to (x, y, z) within distance `r` (at most half the cell size), or -1: such a vertex lies in
   * the point's cell or in its neighbour on the nearer side along each axis (8 cells).
   */
  nearest(x, y, z, r) {
    const { pos, head, next } = this;
    const fx = x * this.inv;
    const fy = y * this.inv;
    const fz = z * this.inv;
    const cx = Math.floor(fx);
    const cy = Math.floor(fy);
    const cz = Math.floor(fz);
    const sx = fx - cx < 0.5 ? -1 : 1;
    const sy = fy - cy < 0.5 ? -1 : 1;
    const sz = fz - cz < 0.5 ? -1 : 1;
    let best = -1;
    let bestD = r * r;
    for (let c = 0; c < 8; c++) {
      const h = this._bucket(cx + (c & 1 ? sx : 0), cy + (c & 2 ? sy : 0), cz + (c & 4 ? sz : 0));
      for (let j = head[h]; j >= 0; j = next[j]) {
        const ex = pos[3 * j] - x;
        const ey = pos[3 * j + 1] - y;
        const ez = pos[3 * j + 2] - z;
        const d = ex * ex + ey * ey + ez * ez;
        if (d <= bestD) {
          bestD = d;
          best = j;
        }
      }
    }
    return best;
  }
}

/** For each vertex in `which` (all when null), the vertex nearest to its reflection within `tol`, or -1. */
function reflectedNearest(pos, hash, pl, tol, which = null) {
  const [a, b, c] = pl.normal;
  const off = a * pl.point[0] + b * pl.point[1] + c * pl.point[2];
  const count = which ? which.length : pos.length / 3;
  const out = new Int32Array(count);
  for (let k = 0; k < count; k++) {
    const i = which ? which[k] : k;
    const x = pos[3 * i];
    const y = pos[3 * i + 1];
    const z = pos[3 * i + 2];
    const s = 2 * (a * x + b * y + c * z - off);
    out[k] = hash.nearest(x - s * a, y - s * b, z - s * c, tol);
  }
  return out;
}

/** The plane fitted to vertex pairs (i, pair[k]) (the vertices `which[k]`): a refinement of `pl`. */
function refit(pos, pl, which, pair) {
  const sum = [0, 0, 0];
  const mid = [0, 0, 0];
  const [nx, ny, nz] = pl.normal;
  let m = 0;
  for (let k = 0; k < pair.length; k++) {
    const j = pair[k];
    if (j < 0) continue;
    const i = which ? which[k] : k;
    const d0 = pos[3 * i] - pos[3 * j];
    const d1 = pos[3 * i + 1] - pos[3 * j + 1];
    const d2 = pos[3 * i + 2] - pos[3 * j + 2];
    const sign = d0 * nx + d1 * ny + d2 * nz < 0 ? -1 : 1;
    sum[0] += sign * d0;
    sum[1] += sign * d1;
    sum[2] += sign * d2;
    mid[0] += (pos[3 * i] + pos[3 * j]) / 2;
    mid[1] += (pos[3 * i + 1] + pos[3 * j + 1]) / 2;
    mid[2] += (pos[3 * i + 2] + pos[3 * j + 2]) / 2;
    m++;
  }
  if (m === 0 || Math.hypot(...sum) === 0) return pl;
  return plane(sum, mid.map((v) => v / m));
}

/** Mutual nearest reflections: mirrorOf[i] = j when each is the other's nearest reflection (an involution). */
function mutual(nearest) {
  const out = new Int32Array(nearest.length).fill(-1);
  let matched = 0;
  for (let i = 0; i < nearest.length; i++) {
    const j = nearest[i];
    if (j >= 0 && nearest[j] === i) {
      out[i] = j;
      matched++;
    }
  }
  return { mirrorOf: out, matched };
}

/** Mean edge length of (a sample of) the triangles. */
function meanEdge(pos, faces) {
  const nf = faces.length / 3;
  const step = Math.max(1, Math.floor(nf / 5000));
  let sum = 0;
  let count = 0;
  for (let f = 0; f < nf; f += step) {
    for (let e = 0; e < 3; e++) {
      const i = faces[3 * f + e];
      const j = faces[3 * f + ((e + 1) % 3)];
      sum += Math.hypot(pos[3 * i] - pos[3 * j], pos[3 * i + 1] - pos[3 * j + 1], pos[3 * i + 2] - pos[3 * j + 2]);
      count++;
    }
  }
  return count ? sum / count : 0;
}

/**
 * Find the mirror symmetry of a mesh.
 * @param {ArrayLike<number>} pos vertex positions, 3 per vertex
 * @param {ArrayLike<number>|null} faces triangle indices (for the tolerance of approximately symmetric meshes)
 * @param {string} axis 'auto' (the best of the bounding-box and principal axes through the centroid), or 'x', 'y'
 *   or 'z' (that axis's plane through the bounding-box centre, however well it matches)
 * @returns {{plane: {normal: number[], point: number[]}|null, mirrorOf: Int32Array|null, matched: number,
 *   tolerance: number, ms: number}} `plane` null when no candidate matches MIN_MATCHED of the vertices (auto);
 *   `matched` the share of vertices with a partner, `tolerance` the distance a reflection may miss its partner
 */
export function detectSymmetry(pos, faces, axis = 'auto') {
  const t0 = performance.now();
  const mo = moments(pos);
  const { n, diag } = mo;
  const none = { plane: null, mirrorOf: null, matched: 0, tolerance: 0, ms: 0 };
  if (n === 0 || !(diag > 0)) return { ...none, ms: performance.now() - t0 };
  const exact = EXACT_TOLERANCE * diag;
  const loose = faces ? Math.min(1e-2 * diag, 0.5 * meanEdge(pos, faces)) : exact;
  const tolerances = loose > exact ? [exact, loose] : [exact];
  const unit = (k) => [0, 1, 2].map((t) => (t === k ? 1 : 0));
  const fixedAxis = AXES.indexOf(axis);
  const candidates = fixedAxis >= 0
    ? [plane(unit(fixedAxis), mo.centre)]
    : [...[0, 1, 2].map(unit), ...eigenvectors3(mo.cov)].map((nrm) => plane(nrm, mo.mean));
  const stride = Math.max(1, Math.floor(n / SAMPLE));
  const sample = [];
  for (let i = 0; i < n; i += stride) sample.push(i);
  let best = none;
  for (const tol of tolerances) {
    const hash = new GridHash(pos, 2 * tol);
    let pl = candidates[0];
    if (fixedAxis < 0) {
      let bestScore = -1;
      let bestPairs = null;
      for (const cand of candidates) {
        const pairs = reflectedNearest(pos, hash, cand, tol, sample);
        const score = pairs.reduce((s, j) => s + (j >= 0 ? 1 : 0), 0);
        if (score > bestScore) {
          bestScore = score;
          bestPairs = pairs;
          pl = cand;
        }
      }
      if (bestScore < 0.5 * MIN_MATCHED * sample.length) continue;
      pl = refit(pos, pl, sample, bestPairs);
    }
    const { mirrorOf, matched } = mutual(reflectedNearest(pos, hash, pl, tol));
    // the plane that fits every pair (a sample's plane may be off by a little more than rounding)
    if (fixedAxis < 0) pl = refit(pos, pl, null, mirrorOf);
    const found = { plane: pl, mirrorOf, matched: matched / n, tolerance: tol, ms: 0 };
    if (found.matched > best.matched) best = found;
    if (best.matched >= MIN_MATCHED) break;
  }
  if (fixedAxis < 0 && best.matched < MIN_MATCHED) best = { ...none, matched: best.matched };
  return { ...best, ms: performance.now() - t0 };
}
