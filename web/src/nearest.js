// Nearest-point queries on a mesh, for the mirror symmetry search (symmetry.js): a k-d tree of vertices that finds
// the vertex nearest to a point within a radius, and a surface that finds the closest point of the triangles around
// that vertex. Every candidate plane asks these thousands of times, so they are kept apart from the search itself,
// in flat typed arrays; a query costs O(log n) whatever its radius. No DOM, no Three.js.

/** Points a leaf of a PointTree holds at most (scanned one by one). */
const LEAF = 8;

/**
 * The vertices `which` (all when null) in a k-d tree (a median split along the widest side of each node's box),
 * for "the vertex nearest to a point, within a radius": a query visits O(log n) nodes whatever the radius and the
 * density of the points, where a grid of cells of about the radius scans every vertex of the cells around the point.
 * `closest` leaves the vertex's position in `point`; `visits` counts the distances computed (the work done).
 */
export class PointTree {
  /**
   * @param {ArrayLike<number>} pos positions, 3 per vertex
   * @param {ArrayLike<number>|null} [which]
   */
  constructor(pos, which = null) {
    const n = which ? which.length : pos.length / 3;
    this.pos = pos;
    /** the vertices, ordered so that each node's are a range, its splitting vertex in the middle */
    this.order = new Int32Array(n);
    for (let k = 0; k < n; k++) this.order[k] = which ? which[k] : k;
    /** the axis each node splits along, by the position of its splitting vertex in `order` */
    this.axis = new Uint8Array(n);
    this.point = [0, 0, 0];
    this.visits = 0;
    /** @type {number[]} ranges [lo, hi) still to split */
    const todo = [0, n];
    while (todo.length) {
      const hi = /** @type {number} */ (todo.pop());
      const lo = /** @type {number} */ (todo.pop());
      if (hi - lo <= LEAF) continue;
      const axis = this._widest(lo, hi);
      const mid = (lo + hi) >> 1;
      this._select(lo, hi, mid, axis);
      this.axis[mid] = axis;
      todo.push(lo, mid, mid + 1, hi);
    }
    // the search's pending nodes: at most one per level of the tree
    let depth = 1;
    for (let size = n; size > LEAF; size >>= 1) depth++;
    this.stackLo = new Int32Array(2 * depth + 2);
    this.stackHi = new Int32Array(2 * depth + 2);
    this.stackD = new Float64Array(2 * depth + 2);
  }

  /** The axis along which the vertices order[lo..hi) spread widest. @param {number} lo @param {number} hi */
  _widest(lo, hi) {
    const { pos, order } = this;
    let axis = 0;
    let widest = -1;
    for (let t = 0; t < 3; t++) {
      let min = Infinity;
      let max = -Infinity;
      for (let k = lo; k < hi; k++) {
        const v = pos[3 * order[k] + t];
        if (v < min) min = v;
        if (v > max) max = v;
      }
      if (max - min > widest) {
        widest = max - min;
        axis = t;
      }
    }
    return axis;
  }

  /**
   * Reorder order[lo..hi) so that order[mid] has the mid-th smallest coordinate along `axis`, with none larger
   * before it and none smaller after it (quickselect).
   * @param {number} lo @param {number} hi @param {number} mid @param {number} axis
   */
  _select(lo, hi, mid, axis) {
    const { pos, order } = this;
    let left = lo;
    let right = hi - 1;
    while (right > left) {
      const pivot = pos[3 * order[(left + right) >> 1] + axis];
      let i = left;
      let j = right;
      while (i <= j) {
        while (pos[3 * order[i] + axis] < pivot) i++;
        while (pos[3 * order[j] + axis] > pivot) j--;
        if (i <= j) {
          const t = order[i];
          order[i] = order[j];
          order[j] = t;
          i++;
          j--;
        }
      }
      if (mid <= j) right = j;
      else if (mid >= i) left = i;
      else return;
    }
  }

  /**
   * The vertex nearest to (x, y, z) within distance `r`, or -1 (of two as near, the lower index).
   * @param {number} x @param {number} y @param {number} z @param {number} r
   */
  nearest(x, y, z, r) {
    const { pos, order, axis, stackLo, stackHi, stackD } = this;
    let best = -1;
    let bestD = r * r;
    let visits = 0;
    let top = 0;
    stackLo[0] = 0;
    stackHi[0] = order.length;
    stackD[0] = 0;
    top = 1;
    while (top > 0) {
      top--;
      if (stackD[top] > bestD) continue; // the splitting plane is farther than the best: nothing nearer beyond it
      let lo = stackLo[top];
      let hi = stackHi[top];
      while (hi - lo > LEAF) {
        const mid = (lo + hi) >> 1;
        const j = order[mid];
        const ex = pos[3 * j] - x;
        const ey = pos[3 * j + 1] - y;
        const ez = pos[3 * j + 2] - z;
        const d = ex * ex + ey * ey + ez * ez;
        visits++;
        if (d < bestD || (d === bestD && (best < 0 || j < best))) {
          bestD = d;
          best = j;
        }
        const a = axis[mid];
        const side = a === 0 ? -ex : a === 1 ? -ey : -ez; // the point's offset from the splitting plane
        // the point's side first; the other side waits on the stack with its distance from the point
        if (side < 0) {
          stackLo[top] = mid + 1;
          stackHi[top] = hi;
          hi = mid;
        } else {
          stackLo[top] = lo;
          stackHi[top] = mid;
          lo = mid + 1;
        }
        stackD[top++] = side * side;
      }
      for (let k = lo; k < hi; k++) {
        const j = order[k];
        const ex = pos[3 * j] - x;
        const ey = pos[3 * j + 1] - y;
        const ez = pos[3 * j + 2] - z;
        const d = ex * ex + ey * ey + ez * ez;
        if (d < bestD || (d === bestD && (best < 0 || j < best))) {
          bestD = d;
          best = j;
        }
      }
      visits += hi - lo;
    }
    this.visits += visits;
    return best;
  }

  /**
   * The vertex nearest to (x, y, z) within `r`, or -1, its position left in `point`.
   * @param {number} x @param {number} y @param {number} z @param {number} r
   */
  closest(x, y, z, r) {
    const j = this.nearest(x, y, z, r);
    if (j >= 0) for (let t = 0; t < 3; t++) this.point[t] = this.pos[3 * j + t];
    return j;
  }
}

/**
 * The surface of a mesh, for "how far is a point from it": the vertex nearest to the point (within `tol` plus about
 * an edge) and the closest point of the triangles around that vertex. Without triangles the vertices stand for
 * the surface.
 */
export class Surface {
  /**
   * @param {ArrayLike<number>} pos positions, 3 per vertex
   * @param {ArrayLike<number>|null} faces triangles, 3 vertex indices each
   * @param {number} tol
   */
  constructor(pos, faces, tol) {
    this.pos = pos;
    this.faces = faces && faces.length ? faces : null;
    const n = pos.length / 3;
    const edge = this.faces ? meanEdge(pos, this.faces) : 0;
    this.reach = tol + 1.5 * edge;
    this.tree = new PointTree(pos);
    this.point = [0, 0, 0];
    this.distance = Infinity;
    /** @type {{faces: ArrayLike<number>, start: Int32Array, around: Int32Array}|null} the triangles at each vertex */
    this.incident = null;
    if (!this.faces) return;
    const f = this.faces;
    const start = new Int32Array(n + 1);
    for (let k = 0; k < f.length; k++) start[f[k] + 1]++;
    for (let i = 0; i < n; i++) start[i + 1] += start[i];
    const fill = start.slice(0, n);
    const around = new Int32Array(f.length);
    for (let k = 0; k < f.length; k++) around[fill[f[k]]++] = (k / 3) | 0;
    this.incident = { faces: f, start, around };
  }

  /**
   * The vertex nearest to (x, y, z) when the surface passes within `tol` of the point (its closest point left in
   * `point`, the distance in `distance`), or -1.
   * @param {number} x @param {number} y @param {number} z @param {number} tol
   */
  closest(x, y, z, tol) {
    const { pos, incident } = this;
    const v = this.tree.nearest(x, y, z, this.reach);
    if (v < 0) return -1;
    const best = this.point;
    let bestD = (pos[3 * v] - x) ** 2 + (pos[3 * v + 1] - y) ** 2 + (pos[3 * v + 2] - z) ** 2;
    for (let t = 0; t < 3; t++) best[t] = pos[3 * v + t];
    if (incident) {
      const { faces, start, around } = incident;
      const q = [0, 0, 0];
      for (let e = start[v]; e < start[v + 1]; e++) {
        const t = around[e];
        const d = closestOnTriangle(pos, faces[3 * t], faces[3 * t + 1], faces[3 * t + 2], x, y, z, q);
        if (d < bestD) {
          bestD = d;
          best[0] = q[0];
          best[1] = q[1];
          best[2] = q[2];
        }
      }
    }
    this.distance = Math.sqrt(bestD);
    return this.distance <= tol ? v : -1;
  }
}

/**
 * Mean edge length of (a sample of) the triangles.
 * @param {ArrayLike<number>} pos positions, 3 per vertex
 * @param {ArrayLike<number>} faces triangles, 3 indices each
 */
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
 * The point of triangle (i, j, k) closest to (x, y, z), written into `out`; its squared distance (Ericson, Real-Time
 * Collision Detection, 5.1.5).
 * @param {ArrayLike<number>} pos positions, 3 per vertex
 * @param {number} i
 * @param {number} j
 * @param {number} k
 * @param {number} x
 * @param {number} y
 * @param {number} z
 * @param {number[]|Float64Array} out x, y, z of the closest point
 * @returns {number}
 */
function closestOnTriangle(pos, i, j, k, x, y, z, out) {
  const ax = pos[3 * i], ay = pos[3 * i + 1], az = pos[3 * i + 2];
  const abx = pos[3 * j] - ax, aby = pos[3 * j + 1] - ay, abz = pos[3 * j + 2] - az;
  const acx = pos[3 * k] - ax, acy = pos[3 * k + 1] - ay, acz = pos[3 * k + 2] - az;
  const apx = x - ax, apy = y - ay, apz = z - az;
  const d1 = abx * apx + aby * apy + abz * apz;
  const d2 = acx * apx + acy * apy + acz * apz;
  let u = 0; // the point is a + u ab + w ac
  let w = 0;
  if (d1 <= 0 && d2 <= 0) {
    u = 0;
    w = 0;
  } else {
    const bpx = x - pos[3 * j], bpy = y - pos[3 * j + 1], bpz = z - pos[3 * j + 2];
    const d3 = abx * bpx + aby * bpy + abz * bpz;
    const d4 = acx * bpx + acy * bpy + acz * bpz;
    const cpx = x - pos[3 * k], cpy = y - pos[3 * k + 1], cpz = z - pos[3 * k + 2];
    const d5 = abx * cpx + aby * cpy + abz * cpz;
    const d6 = acx * cpx + acy * cpy + acz * cpz;
    const vc = d1 * d4 - d3 * d2;
    const vb = d5 * d2 - d1 * d6;
    const va = d3 * d6 - d5 * d4;
    if (d3 >= 0 && d4 <= d3) {
      u = 1;
    } else if (d6 >= 0 && d5 <= d6) {
      w = 1;
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
      u = d1 / (d1 - d3);
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
      w = d2 / (d2 - d6);
    } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
      w = (d4 - d3) / (d4 - d3 + (d5 - d6));
      u = 1 - w;
    } else {
      const den = 1 / (va + vb + vc);
      u = vb * den;
      w = vc * den;
    }
  }
  out[0] = ax + u * abx + w * acx;
  out[1] = ay + u * aby + w * acy;
  out[2] = az + u * abz + w * acz;
  return (out[0] - x) ** 2 + (out[1] - y) ** 2 + (out[2] - z) ** 2;
}
