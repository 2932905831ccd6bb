// Constraints documents name the vertices of the mesh file, as `arap deform` reads them; the studio works on the mesh
// as repair left it (copies of one vertex welded, vertices that no face uses dropped). The server sends the map with
// the mesh (`meshArrays(frame).vertexMap`: the mesh vertex of each file vertex, -1 for a dropped one) and writes the
// documents it gives out in the file's numbering; a document read here is put into the mesh's numbering, with the
// same rules as `arap deform` (Constraints.remapped): copies of one vertex merge when they agree (all fixed, or
// handles of one group with the same target, or the same stiffness), anything else is refused naming the file's
// vertices. The browser's saved sessions keep the mesh's numbering (the same file is repaired the same way again).

const welded = (/** @type {number} */ a, /** @type {number} */ b) => `file vertices ${a} and ${b} are copies of one vertex (mesh repair welded them)`;
const fmt = (/** @type {number|string} */ v) => (v === 'rigid' ? 'rigid' : String(v));

/**
 * The mesh vertex of file vertex `i` of a constraint role (`what`), refusing a vertex repair dropped.
 * @param {Int32Array} vertexMap
 * @param {number} i
 * @param {string} what
 */
function meshVertex(vertexMap, i, what) {
  const v = vertexMap[i];
  if (v < 0) {
    throw new Error(`${what} vertex ${i} of the file is not in the studio's mesh: mesh repair removed it (no face `
      + 'uses it)');
  }
  return v;
}

/** A painted stiffness group: vertices and their stiffness (a number or 'rigid'). @typedef {{vertices: number[], value: number|string}} StiffnessGroup */

/**
 * The targets (Map file vertex → [x, y, z]) by mesh vertex; copies must have the same target.
 * @param {Map<number, number[]>|null} targets
 * @param {Int32Array} vertexMap
 * @returns {Map<number, number[]>|null}
 */
function mapTargets(targets, vertexMap) {
  if (!targets) return null;
  /** @type {Map<number, number[]>} */
  const out = new Map();
  /** @type {Map<number, number>} mesh vertex → the file vertex whose target it took */
  const from = new Map();
  for (const [i, p] of targets) {
    const v = meshVertex(vertexMap, i, 'handle');
    const q = out.get(v);
    if (q === undefined) {
      out.set(v, p);
      from.set(v, i);
      continue;
    }
    const tol = 1e-12 * Math.max(1, ...p.map(Math.abs), ...q.map(Math.abs));
    if (p.some((x, k) => Math.abs(x - q[k]) > tol)) {
      throw new Error(`${welded(/** @type {number} */ (from.get(v)), i)} but their targets differ: [${q.join(', ')}] and [${p.join(', ')}]`);
    }
  }
  return out;
}

/**
 * Painted stiffness ([{vertices, value}] of file vertices) of the mesh; every copy of a vertex must agree.
 * @param {StiffnessGroup[]|null} stiffness
 * @param {Int32Array} vertexMap
 * @param {number} nVertices
 * @returns {StiffnessGroup[]|null}
 */
function mapStiffness(stiffness, vertexMap, nVertices) {
  if (!stiffness) return null;
  /** @type {Map<number, [number|string, number]>} */
  const value = new Map(); // mesh vertex → [value, file vertex]
  const painted = new Int32Array(nVertices);
  for (const g of stiffness) {
    for (const i of g.vertices) {
      const v = vertexMap[i];
      if (v < 0) continue; // a vertex no face uses has no cell: arap deform ignores its stiffness too
      const seen = value.get(v);
      if (seen && seen[0] !== g.value) {
        throw new Error(`${welded(seen[1], i)} but their stiffness differs: ${fmt(seen[0])} and ${fmt(g.value)}`);
      }
      if (!seen) value.set(v, [g.value, i]);
      painted[v]++;
    }
  }
  const copies = new Int32Array(nVertices);
  for (const v of vertexMap) if (v >= 0) copies[v]++;
  for (const [v, [x, i]] of value) {
    if (painted[v] === copies[v] || x === 1) continue;
    const given = new Set(stiffness.flatMap((g) => g.vertices));
    const other = vertexMap.findIndex((w, j) => w === v && !given.has(j));
    throw new Error(`${welded(i, other)} but their stiffness differs: ${fmt(x)} and 1 (not given)`);
  }
  /** @type {Map<number|string, number[]>} */
  const groups = new Map();
  for (const [v, [x]] of value) {
    if (!groups.has(x)) groups.set(x, []);
    /** @type {number[]} */ (groups.get(x)).push(v);
  }
  return [...groups].map(([x, vertices]) => ({ vertices, value: x }));
}

/**
 * A parsed constraints document (files.js parseConstraints) of the mesh file, in the numbering of the studio's mesh.
 * Fixed vertices and handles that repair dropped, and welded copies that disagree (fixed and handle, handles of two
 * groups or with different targets, different stiffness), are refused with an Error naming the file's vertices; the
 * region of interest and painted stiffness may name dropped vertices (they have no cell; arap deform ignores them).
 * @template {{roi: number[]|null, fixed: number[], handle_groups: number[][], targets: Map<number, number[]>|null,
 *   stiffness: {vertices: number[], value: number|string}[]|null}} T
 * @param {T} c
 * @param {Int32Array} vertexMap mesh vertex of each file vertex, -1 for a dropped one
 * @param {number} nVertices vertices of the mesh
 * @returns {T}
 */
export function toMeshNumbering(c, vertexMap, nVertices) {
  /** @type {Map<number, [number, string, number]>} */
  const role = new Map(); // mesh vertex → [role, label, file vertex]
  /**
   * @param {number} i file vertex
   * @param {number} v its mesh vertex
   * @param {number} r its role: -1 fixed, k handle group k
   * @param {string} label the role in words
   */
  const claim = (i, v, r, label) => {
    const seen = role.get(v);
    if (seen && seen[2] === i) return true; // a vertex repeated in the document: the server's validator answers
    if (!seen) {
      role.set(v, [r, label, i]);
      return true;
    }
    if (seen[0] === r) return false; // another copy in the same role: one vertex
    throw new Error(`${welded(seen[2], i)} but one is ${seen[1]} and the other ${label}`);
  };
  /** @type {number[]} */
  const fixed = [];
  for (const i of c.fixed) {
    const v = meshVertex(vertexMap, i, 'fixed');
    if (claim(i, v, -1, 'fixed')) fixed.push(v);
  }
  const groups = c.handle_groups.map((g, k) => {
    /** @type {number[]} */
    const out = [];
    for (const i of g) {
      const v = meshVertex(vertexMap, i, 'handle');
      if (claim(i, v, k, `in handle group ${k + 1}`)) out.push(v);
    }
    return out;
  });
  let roi = null;
  if (c.roi) {
    roi = [...new Set(Array.from(c.roi, (i) => vertexMap[i]).filter((v) => v >= 0))];
    if (!roi.length) throw new Error('every vertex of the region of interest was removed by mesh repair');
  }
  return {
    ...c,
    roi,
    fixed,
    handle_groups: groups,
    targets: mapTargets(c.targets, vertexMap),
    stiffness: mapStiffness(c.stiffness, vertexMap, nVertices),
  };
}

/**
 * A mesh laid out in the numbering of its file, so that repair turns it back into the same mesh with the same map
 * (a saved session restored from it keeps the file's numbering in its documents): each file vertex at the position
 * of its mesh vertex (the vertices repair dropped together, away from the mesh), and the corners of each vertex
 * spread over its copies (the first corner on the first copy), as repair welds copies that faces use.
 * @param {ArrayLike<number>} positions mesh positions, 3 per vertex
 * @param {ArrayLike<number>} faces mesh triangles, 3 indices each
 * @param {Int32Array} vertexMap mesh vertex of each file vertex, -1 for a dropped one
 * @returns {{positions: Float32Array, faces: Uint32Array}}
 */
export function inFileNumbering(positions, faces, vertexMap) {
  const n = positions.length / 3;
  const starts = new Int32Array(n + 1);
  for (const v of vertexMap) if (v >= 0) starts[v + 1]++;
  for (let v = 0; v < n; v++) starts[v + 1] += starts[v];
  const copies = new Int32Array(starts[n]);
  const fill = starts.slice(0, n);
  vertexMap.forEach((v, i) => {
    if (v >= 0) copies[fill[v]++] = i;
  });
  const lo = [Infinity, Infinity, Infinity];
  const hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < 3 * n; i++) {
    lo[i % 3] = Math.min(lo[i % 3], positions[i]);
    hi[i % 3] = Math.max(hi[i % 3], positions[i]);
  }
  const away = hi.map((h, k) => h + (h - lo[k]) + 1);
  const out = new Float32Array(3 * vertexMap.length);
  vertexMap.forEach((v, i) => {
    for (let k = 0; k < 3; k++) out[3 * i + k] = v >= 0 ? positions[3 * v + k] : away[k];
  });
  const used = new Int32Array(n);
  const F = new Uint32Array(faces.length);
  for (let c = 0; c < faces.length; c++) {
    const v = faces[c];
    const count = starts[v + 1] - starts[v];
    F[c] = copies[starts[v] + (used[v]++ % count)];
  }
  return { positions: out, faces: F };
}
