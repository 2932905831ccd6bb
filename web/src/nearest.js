// Nearest-point queries on a mesh, for the mirror symmetry search (symmetry.js): a uniform grid hash of vertices
// that finds the vertex nearest to a point within a radius, and a surface that finds the closest point of the
// triangles around that vertex. Every candidate plane asks these thousands of times, so they are kept apart from
// the search itself, in flat typed arrays that make each query cost O(1). No DOM, no Three.js.

/**
 * Hash of integer cell coordinates into a power-of-two table.
 * @param {number} ix @param {number} iy @param {number} iz @param {number} mask
 */
function cellHash(ix, iy, iz, mask) {
  return (Math.imul(ix, 73856093) ^ Math.imul(iy, 19349663) ^ Math.imul(iz, 83492791)) & mask;
}

/**
 * The vertices `which` (all when null) in a uniform grid of cell size `cell`, hashed into buckets: the nearest one
 * within `cell` / 2 of a point lies in the point's cell or in its neighbour on the nearer side along each axis (8
 * cells). `closest` leaves the vertex's position in `point`.
 */
export class VertexGrid {
  /**
   * @param {ArrayLike<number>} pos positions, 3 per vertex
   * @param {number} cell
   * @param {ArrayLike<number>|null} [which]
   */
  constructor(pos, cell, which = null) {
    const n = which ? which.length : pos.length / 3;
    this.pos = pos;
    this.inv = 1 / cell;
    let size = 1;
    while (size < 2 * n) size <<= 1;
    this.mask = size - 1;
    this.head = new Int32Array(size).fill(-1);
    this.next = new Int32Array(n);
    this.vertex = new Int32Array(n);
    for (let k = 0; k < n; k++) {
      const i = which ? which[k] : k;
      const h = cellHash(Math.floor(pos[3 * i] * this.inv), Math.floor(pos[3 * i + 1] * this.inv),
        Math.floor(pos[3 * i + 2] * this.inv), this.mask);
      this.vertex[k] = i;
      this.next[k] = this.head[h];
      this.head[h] = k;
    }
    this.point = [0, 0, 0];
  }

  /**
   * The vertex nearest to (x, y, z) within distance `r` (at most half the cell size), or -1.
   * @param {number} x @param {number} y @param {number} z @param {number} r
   */
  nearest(x, y, z, r) {
    const { pos, head, next, vertex } = this;
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
      const h = cellHash(cx + (c & 1 ? sx : 0), cy + (c & 2 ? sy : 0), cz + (c & 4 ? sz : 0), this.mask);
      for (let k = head[h]; k >= 0; k = next[k]) {
        const j = vertex[k];
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
    this.grid = new VertexGrid(pos, 2 * this.reach);
    // most points asked about are within about an edge of a vertex: a finer grid finds it among fewer
    this.step = Math.min(this.reach, Math.max(1.5 * edge, tol / 4));
    this.fine = this.step < this.reach / 2 ? new VertexGrid(pos, 2 * this.step) : null;
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
    let v = this.fine ? this.fine.nearest(x, y, z, this.step) : -1;
    if (v < 0) v = this.grid.nearest(x, y, z, this.reach);
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
