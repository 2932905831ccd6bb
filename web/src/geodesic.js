// Selection along the surface: vertex adjacency in CSR layout (built once per mesh), geodesic balls by Dijkstra over
// the edges, connected patches, one-ring growing and shrinking, and k-ring / distance regions grown from seeds.

/**
 * Vertex adjacency of a triangle mesh in CSR layout: the neighbours of vertex i are `adj[ptr[i]..ptr[i+1]]`.
 * @param {Uint32Array|Int32Array|number[]} faces (m*3) vertex indices
 * @param {number} n number of vertices
 * @returns {{ptr: Int32Array, adj: Int32Array}}
 */
export function buildAdjacency(faces, n) {
  const m = faces.length / 3;
  // every triangle gives each corner its two other corners; duplicates (shared edges) are removed per vertex
  const count = new Int32Array(n + 1);
  for (let k = 0; k < 3 * m; k++) count[faces[k] + 1] += 2;
  for (let i = 0; i < n; i++) count[i + 1] += count[i];
  const fill = count.slice(0, n);
  const raw = new Int32Array(count[n]);
  for (let t = 0; t < m; t++) {
    const a = faces[3 * t];
    const b = faces[3 * t + 1];
    const c = faces[3 * t + 2];
    raw[fill[a]++] = b;
    raw[fill[a]++] = c;
    raw[fill[b]++] = c;
    raw[fill[b]++] = a;
    raw[fill[c]++] = a;
    raw[fill[c]++] = b;
  }
  const ptr = new Int32Array(n + 1);
  const adj = new Int32Array(raw.length);
  let out = 0;
  for (let i = 0; i < n; i++) {
    ptr[i] = out;
    const row = raw.subarray(count[i], count[i + 1]).sort();
    for (let k = 0; k < row.length; k++) if (k === 0 || row[k] !== row[k - 1]) adj[out++] = row[k];
  }
  ptr[n] = out;
  return { ptr, adj: adj.slice(0, out) };
}

/** A binary min-heap of (key, vertex) pairs in typed arrays, grown on demand. */
class MinHeap {
  constructor(capacity = 1024) {
    this.keys = new Float64Array(capacity);
    this.vals = new Int32Array(capacity);
    this.size = 0;
    this.topKey = 0; // the key and vertex of the entry last popped
    this.topVal = 0;
  }

  /** @param {number} key @param {number} val */
  push(key, val) {
    if (this.size === this.keys.length) {
      const keys = new Float64Array(2 * this.size);
      const vals = new Int32Array(2 * this.size);
      keys.set(this.keys);
      vals.set(this.vals);
      this.keys = keys;
      this.vals = vals;
    }
    let i = this.size++;
    while (i > 0) {
      const p = (i - 1) >> 1;
      if (this.keys[p] <= key) break;
      this.keys[i] = this.keys[p];
      this.vals[i] = this.vals[p];
      i = p;
    }
    this.keys[i] = key;
    this.vals[i] = val;
  }

  /** Remove the smallest entry; its key and vertex are then in `topKey` and `topVal`. */
  pop() {
    this.topKey = this.keys[0];
    this.topVal = this.vals[0];
    const key = this.keys[--this.size];
    const val = this.vals[this.size];
    let i = 0;
    for (;;) {
      let c = 2 * i + 1;
      if (c >= this.size) break;
      if (c + 1 < this.size && this.keys[c + 1] < this.keys[c]) c++;
      if (this.keys[c] >= key) break;
      this.keys[i] = this.keys[c];
      this.vals[i] = this.vals[c];
      i = c;
    }
    this.keys[i] = key;
    this.vals[i] = val;
  }
}

/**
 * Vertices within a distance along the edges from seeds (Dijkstra), nearest first. Scratch arrays are kept on the
 * graph, so a call allocates little and costs in proportion to the vertices it reaches.
 * @param {{ptr: Int32Array, adj: Int32Array, dist?: Float64Array}} graph from buildAdjacency
 * @param {ArrayLike<number>} positions (n*3)
 * @param {Array<[number, number]>} seeds [vertex, starting distance] pairs (e.g. the corners of a hit triangle with
 *   their distance to the hit point)
 * @param {number} radius largest distance kept
 * @returns {{vertices: number[], distances: number[]}} every vertex within the radius and its distance
 */
export function geodesicDistances(graph, positions, seeds, radius) {
  const { ptr, adj } = graph;
  const n = ptr.length - 1;
  let dist = graph.dist; // Infinity everywhere between calls
  if (!dist || dist.length !== n) dist = graph.dist = new Float64Array(n).fill(Infinity);
  const vertices = [];
  const distances = [];
  const heap = new MinHeap();
  for (const [v, d] of seeds) if (d <= radius) heap.push(d, v);
  while (heap.size) {
    heap.pop();
    const v = heap.topVal;
    const d = heap.topKey;
    if (dist[v] !== Infinity) continue;
    dist[v] = d;
    vertices.push(v);
    distances.push(d);
    const x = positions[3 * v];
    const y = positions[3 * v + 1];
    const z = positions[3 * v + 2];
    for (let k = ptr[v]; k < ptr[v + 1]; k++) {
      const w = adj[k];
      if (dist[w] !== Infinity) continue;
      const dx = positions[3 * w] - x;
      const dy = positions[3 * w + 1] - y;
      const dz = positions[3 * w + 2] - z;
      const dw = d + Math.sqrt(dx * dx + dy * dy + dz * dz);
      if (dw <= radius) heap.push(dw, w);
    }
  }
  for (const v of vertices) dist[v] = Infinity;
  return { vertices, distances };
}

/**
 * The corners of triangle `face` with their straight distance to `point`, as seeds.
 * @param {ArrayLike<number>} positions (n*3)
 * @param {{a: number, b: number, c: number}} face
 * @param {{x: number, y: number, z: number}} point
 * @returns {Array<[number, number]>}
 */
export function triangleSeeds(positions, face, point) {
  return [face.a, face.b, face.c].map((v) => {
    const dx = positions[3 * v] - point.x;
    const dy = positions[3 * v + 1] - point.y;
    const dz = positions[3 * v + 2] - point.z;
    return /** @type {[number, number]} */ ([v, Math.sqrt(dx * dx + dy * dy + dz * dz)]);
  });
}

/**
 * The patch connected to the seeds through vertices that lie within `radius` (straight distance) of `point`: a
 * ball cut down to the piece of surface under the cursor, without parts that only come near it.
 * @param {{ptr: Int32Array, adj: Int32Array}} graph from buildAdjacency
 * @param {ArrayLike<number>} positions (n*3)
 * @param {Iterable<number>} seeds
 * @param {{x: number, y: number, z: number}} point
 * @param {number} radius
 * @returns {number[]} vertex indices
 */
export function connectedPatch(graph, positions, seeds, point, radius) {
  const { ptr, adj } = graph;
  const r2 = radius * radius;
  const inside = (/** @type {number} */ v) => {
    const dx = positions[3 * v] - point.x;
    const dy = positions[3 * v + 1] - point.y;
    const dz = positions[3 * v + 2] - point.z;
    return dx * dx + dy * dy + dz * dz <= r2;
  };
  /** @type {Set<number>} */
  const seen = new Set();
  /** @type {number[]} */
  const stack = [];
  for (const v of seeds) {
    if (!seen.has(v) && inside(v)) {
      seen.add(v);
      stack.push(v);
    }
  }
  while (stack.length) {
    const v = /** @type {number} */ (stack.pop());
    for (let k = ptr[v]; k < ptr[v + 1]; k++) {
      const w = adj[k];
      if (!seen.has(w) && inside(w)) {
        seen.add(w);
        stack.push(w);
      }
    }
  }
  return [...seen];
}

/**
 * One ring around a vertex set: the outside neighbours of members (grow), or the members with an outside
 * neighbour (shrink).
 * @param {{ptr: Int32Array, adj: Int32Array}} graph from buildAdjacency
 * @param {number} n number of vertices
 * @param {(i: number) => boolean} member
 * @param {boolean} [shrink]
 * @returns {number[]} the vertices to add (grow) or remove (shrink)
 */
export function ringAround(graph, n, member, shrink = false) {
  const { ptr, adj } = graph;
  /** @type {number[]} */
  const out = [];
  for (let v = 0; v < n; v++) {
    if (member(v) === shrink) {
      // grow: v outside, added when a neighbour is a member; shrink: v a member, removed when a neighbour is not
      for (let k = ptr[v]; k < ptr[v + 1]; k++) {
        if (member(adj[k]) !== shrink) {
          out.push(v);
          break;
        }
      }
    }
  }
  return out;
}

/**
 * Vertices within `k` rings of the seeds (breadth-first over the edges).
 * @param {{ptr: Int32Array, adj: Int32Array}} graph from buildAdjacency
 * @param {number[]} seeds
 * @param {number} k
 * @returns {number[]}
 */
export function kRing(graph, seeds, k) {
  const { ptr, adj } = graph;
  const seen = new Set(seeds);
  let front = [...seen];
  for (let ring = 0; ring < k && front.length; ring++) {
    const next = [];
    for (const v of front) {
      for (let e = ptr[v]; e < ptr[v + 1]; e++) {
        const w = adj[e];
        if (!seen.has(w)) {
          seen.add(w);
          next.push(w);
        }
      }
    }
    front = next;
  }
  return [...seen];
}
