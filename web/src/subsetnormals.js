// Vertex normals of the part of a mesh that moved: area-weighted face normals summed per vertex (as Three.js's
// computeVertexNormals), recomputed only for the vertices whose normal a move of the movable vertices changes.
// The face lists are built once per movable list; a frame then allocates nothing.

function addTo(normals, i, x, y, z) {
  normals[i] += x;
  normals[i + 1] += y;
  normals[i + 2] += z;
}

/** Normals to recompute when `movable` (Uint32Array) move, for faces `index` (Uint32Array, 3 per face). */
export class SubsetNormals {
  constructor(index, nVertices, movable) {
    const nf = index.length / 3;
    const moving = new Uint8Array(nVertices);
    for (let k = 0; k < movable.length; k++) moving[movable[k]] = 1;
    // touched: vertices of the faces around a movable vertex (their normals change)
    const touched = new Uint8Array(nVertices);
    for (let f = 0; f < nf; f++) {
      const a = index[3 * f], b = index[3 * f + 1], c = index[3 * f + 2];
      if (moving[a] || moving[b] || moving[c]) touched[a] = touched[b] = touched[c] = 1;
    }
    // every face around a touched vertex contributes to its normal
    let count = 0;
    for (let f = 0; f < nf; f++) {
      if (touched[index[3 * f]] || touched[index[3 * f + 1]] || touched[index[3 * f + 2]]) count++;
    }
    this.faces = new Uint32Array(3 * count);
    for (let f = 0, o = 0; f < nf; f++) {
      if (touched[index[3 * f]] || touched[index[3 * f + 1]] || touched[index[3 * f + 2]]) {
        this.faces[o++] = index[3 * f];
        this.faces[o++] = index[3 * f + 1];
        this.faces[o++] = index[3 * f + 2];
      }
    }
    let nt = 0;
    for (let i = 0; i < nVertices; i++) nt += touched[i];
    this.vertices = new Uint32Array(nt);
    for (let i = 0, o = 0; i < nVertices; i++) if (touched[i]) this.vertices[o++] = i;
    this.touched = touched;
    this.movable = movable;
    this.first = nt ? this.vertices[0] : 0;
    this.last = nt ? this.vertices[nt - 1] : -1;
  }

  /** Recompute `normals` (Float32Array, 3 per vertex) of the touched vertices from `pos`. */
  update(pos, normals) {
    const vs = this.vertices, fs = this.faces, touched = this.touched;
    for (let k = 0; k < vs.length; k++) {
      const i = 3 * vs[k];
      normals[i] = normals[i + 1] = normals[i + 2] = 0;
    }
    for (let o = 0; o < fs.length; o += 3) {
      const a = 3 * fs[o], b = 3 * fs[o + 1], c = 3 * fs[o + 2];
      const ux = pos[c] - pos[b], uy = pos[c + 1] - pos[b + 1], uz = pos[c + 2] - pos[b + 2];
      const vx = pos[a] - pos[b], vy = pos[a + 1] - pos[b + 1], vz = pos[a + 2] - pos[b + 2];
      const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      if (touched[a / 3]) addTo(normals, a, nx, ny, nz);
      if (touched[b / 3]) addTo(normals, b, nx, ny, nz);
      if (touched[c / 3]) addTo(normals, c, nx, ny, nz);
    }
    for (let k = 0; k < vs.length; k++) {
      const i = 3 * vs[k];
      const l = Math.hypot(normals[i], normals[i + 1], normals[i + 2]) || 1;
      normals[i] /= l;
      normals[i + 1] /= l;
      normals[i + 2] /= l;
    }
  }
}
