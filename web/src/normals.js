// Vertex normals and bounds of the deforming mesh, on typed arrays (no per-vertex objects, nothing allocated per
// frame). A vertex normal is the sum of the area-weighted normals (b→c × b→a, as Three.js's computeVertexNormals)
// of the faces around it, normalised. Full frames recompute every normal; subset frames recompute only the normals
// that a move of the movable vertices changes: those of the movable vertices and their one-ring, found through a
// vertex→face adjacency (CSR) built once per mesh.

/** A geometry attribute's array (normals: Float32Array). @typedef {import('three/src/core/BufferAttribute.js').TypedArray} TypedArray */

/** Faces around each vertex: faces of vertex v are `faces[offsets[v]..offsets[v+1]]`. */
export class VertexFaces {
  /** @param {Uint32Array} index 3 vertex indices per face. @param {number} nVertices */
  constructor(index, nVertices) {
    const offsets = new Uint32Array(nVertices + 1);
    for (let k = 0; k < index.length; k++) offsets[index[k] + 1]++;
    for (let v = 0; v < nVertices; v++) offsets[v + 1] += offsets[v];
    const fill = offsets.slice(0, nVertices);
    const faces = new Uint32Array(index.length);
    for (let k = 0; k < index.length; k++) faces[fill[index[k]]++] = (k / 3) | 0;
    this.offsets = offsets;
    this.faces = faces;
    this.index = index;
    this.nVertices = nVertices;
    this.nFaces = index.length / 3;
  }
}

/**
 * @param {TypedArray} normals 3 per vertex
 * @param {number} i the first of a vertex's three
 */
function normalise(normals, i) {
  const x = normals[i], y = normals[i + 1], z = normals[i + 2];
  const l = Math.sqrt(x * x + y * y + z * z) || 1;
  normals[i] = x / l;
  normals[i + 1] = y / l;
  normals[i + 2] = z / l;
}

/**
 * Every vertex normal of `pos` (Float32Array, 3 per vertex) into `normals` (same length).
 * @param {ArrayLike<number>} pos
 * @param {ArrayLike<number>} index 3 vertex indices per face
 * @param {TypedArray} normals
 */
export function computeNormals(pos, index, normals) {
  normals.fill(0);
  for (let o = 0; o < index.length; o += 3) {
    const a = 3 * index[o], b = 3 * index[o + 1], c = 3 * index[o + 2];
    const ux = pos[c] - pos[b], uy = pos[c + 1] - pos[b + 1], uz = pos[c + 2] - pos[b + 2];
    const vx = pos[a] - pos[b], vy = pos[a + 1] - pos[b + 1], vz = pos[a + 2] - pos[b + 2];
    const x = uy * vz - uz * vy, y = uz * vx - ux * vz, z = ux * vy - uy * vx;
    normals[a] += x; normals[a + 1] += y; normals[a + 2] += z;
    normals[b] += x; normals[b + 1] += y; normals[b + 2] += z;
    normals[c] += x; normals[c + 1] += y; normals[c + 2] += z;
  }
  for (let i = 0; i < normals.length; i += 3) normalise(normals, i);
}

/** Normals to recompute when the vertices `movable` (Uint32Array) move. */
export class SubsetNormals {
  /** @param {VertexFaces} adjacency @param {Uint32Array} movable */
  constructor(adjacency, movable) {
    const { offsets, faces, index, nVertices } = adjacency;
    // touched: the vertices of the faces around a movable vertex (their normals change)
    const touched = new Uint8Array(nVertices);
    /** @type {number[]} */
    const list = [];
    const mark = (/** @type {number} */ v) => {
      if (!touched[v]) {
        touched[v] = 1;
        list.push(v);
      }
    };
    for (let k = 0; k < movable.length; k++) {
      const v = movable[k];
      for (let j = offsets[v]; j < offsets[v + 1]; j++) {
        const f = 3 * faces[j];
        mark(index[f]);
        mark(index[f + 1]);
        mark(index[f + 2]);
      }
    }
    // every face around a touched vertex contributes to its normal; each is listed once
    const seen = new Uint8Array(adjacency.nFaces);
    const around = [];
    for (const v of list) {
      for (let j = offsets[v]; j < offsets[v + 1]; j++) {
        const f = faces[j];
        if (!seen[f]) {
          seen[f] = 1;
          around.push(f);
        }
      }
    }
    around.sort((x, y) => x - y);
    this.faces = new Uint32Array(3 * around.length);
    this.corners = new Uint8Array(3 * around.length); // 1 where the corner's vertex is touched
    around.forEach((f, k) => {
      for (let c = 0; c < 3; c++) {
        const v = index[3 * f + c];
        this.faces[3 * k + c] = 3 * v;
        this.corners[3 * k + c] = touched[v];
      }
    });
    this.vertices = Uint32Array.from(list).sort();
    this.movable = movable;
    this.first = list.length ? this.vertices[0] : 0;
    this.last = list.length ? this.vertices[list.length - 1] : -1;
  }

  /**
   * Recompute `normals` (Float32Array, 3 per vertex) of the touched vertices from `pos`.
   * @param {ArrayLike<number>} pos
   * @param {TypedArray} normals
   */
  update(pos, normals) {
    const vs = this.vertices, fs = this.faces, corners = this.corners;
    for (let k = 0; k < vs.length; k++) {
      const i = 3 * vs[k];
      normals[i] = normals[i + 1] = normals[i + 2] = 0;
    }
    for (let o = 0; o < fs.length; o += 3) {
      const a = fs[o], b = fs[o + 1], c = fs[o + 2];
      const ux = pos[c] - pos[b], uy = pos[c + 1] - pos[b + 1], uz = pos[c + 2] - pos[b + 2];
      const vx = pos[a] - pos[b], vy = pos[a + 1] - pos[b + 1], vz = pos[a + 2] - pos[b + 2];
      const x = uy * vz - uz * vy, y = uz * vx - ux * vz, z = ux * vy - uy * vx;
      if (corners[o]) { normals[a] += x; normals[a + 1] += y; normals[a + 2] += z; }
      if (corners[o + 1]) { normals[b] += x; normals[b + 1] += y; normals[b + 2] += z; }
      if (corners[o + 2]) { normals[c] += x; normals[c + 1] += y; normals[c + 2] += z; }
    }
    for (let k = 0; k < vs.length; k++) normalise(normals, 3 * vs[k]);
  }
}

/**
 * Bounding box and sphere of `pos` (Float32Array, 3 per vertex) into a Three.js Box3 and Sphere: the sphere is
 * centred on the box, with the largest distance of a vertex as radius (as Three.js's computeBoundingSphere).
 * @param {ArrayLike<number>} pos
 * @param {import('three').Box3} box
 * @param {import('three').Sphere} sphere
 */
export function computeBounds(pos, box, sphere) {
  let x0 = Infinity, y0 = Infinity, z0 = Infinity, x1 = -Infinity, y1 = -Infinity, z1 = -Infinity;
  for (let i = 0; i < pos.length; i += 3) {
    const x = pos[i], y = pos[i + 1], z = pos[i + 2];
    if (x < x0) x0 = x;
    if (x > x1) x1 = x;
    if (y < y0) y0 = y;
    if (y > y1) y1 = y;
    if (z < z0) z0 = z;
    if (z > z1) z1 = z;
  }
  box.min.set(x0, y0, z0);
  box.max.set(x1, y1, z1);
  const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2, cz = (z0 + z1) / 2;
  let r2 = 0;
  for (let i = 0; i < pos.length; i += 3) {
    const dx = pos[i] - cx, dy = pos[i + 1] - cy, dz = pos[i + 2] - cz;
    const d2 = dx * dx + dy * dy + dz * dz;
    if (d2 > r2) r2 = d2;
  }
  sphere.center.set(cx, cy, cz);
  sphere.radius = Math.sqrt(r2);
}
