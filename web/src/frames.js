// Binary frames of the studio protocol (docs/protocol.md, "Binary frames"): a u32 little-endian header length, the
// JSON header padded with spaces so that the payload starts at a multiple of 4 bytes, then the payload. Building and
// splitting frames, and reading the arrays of `mesh` and `vertices` frames without copying where they are aligned.
// The Python side is arap.server.frames; a test runs both on the same frames.

const textEncoder = new TextEncoder();
const textDecoder = new TextDecoder();

/**
 * Build a binary frame: u32 little-endian header length, the JSON header padded with spaces so that the
 * payload starts at a multiple of 4 bytes, then the payload.
 * @param {import('./protocol.js').ClientMessage|import('./protocol.js').ServerMessage} header JSON header.
 * @param {ArrayBuffer|ArrayBufferView} [payload] payload bytes.
 * @returns {ArrayBuffer}
 */
export function encodeBinary(header, payload) {
  let json = JSON.stringify(header);
  let head = textEncoder.encode(json);
  const pad = (4 - ((4 + head.length) % 4)) % 4;
  if (pad) {
    json += ' '.repeat(pad);
    head = textEncoder.encode(json);
  }
  /** @type {Uint8Array} */
  let body = new Uint8Array(0);
  if (payload instanceof ArrayBuffer) {
    body = new Uint8Array(payload);
  } else if (payload) {
    body = new Uint8Array(payload.buffer, payload.byteOffset, payload.byteLength);
  }
  const out = new Uint8Array(4 + head.length + body.length);
  new DataView(out.buffer).setUint32(0, head.length, true);
  out.set(head, 4);
  out.set(body, 4 + head.length);
  return out.buffer;
}

/**
 * Split a binary frame into its JSON header and its payload (a view, no copy).
 * @param {ArrayBuffer} buffer
 * @returns {{header: any, payload: Uint8Array}} the header as sent (checked by its reader)
 */
export function decodeBinary(buffer) {
  if (buffer.byteLength < 4) {
    throw new Error('binary frame shorter than its 4-byte header length');
  }
  const n = new DataView(buffer).getUint32(0, true);
  if (4 + n > buffer.byteLength) {
    throw new Error(`binary frame header length ${n} exceeds the frame (${buffer.byteLength} bytes)`);
  }
  const header = JSON.parse(textDecoder.decode(new Uint8Array(buffer, 4, n)));
  return { header, payload: new Uint8Array(buffer, 4 + n) };
}

/**
 * `count` float32 values of a payload from `offsetBytes`: a view where the offset is aligned, else a copy.
 * @param {Uint8Array} payload
 * @param {number} offsetBytes
 * @param {number} count
 * @returns {Float32Array}
 */
function floatView(payload, offsetBytes, count) {
  const start = payload.byteOffset + offsetBytes;
  if (start % 4 === 0) {
    return new Float32Array(payload.buffer, start, count);
  }
  return new Float32Array(payload.slice(offsetBytes, offsetBytes + 4 * count).buffer);
}

/**
 * Arrays of a `mesh` frame: positions, triangles and, when repair renumbered the file's vertices, `vertexMap` (the
 * mesh vertex each file vertex became, -1 for a dropped one; else null).
 * @param {{header: {n_vertices: number, n_faces: number, file_vertices?: number}, payload: Uint8Array}} frame
 *   a `mesh` frame (result of decodeBinary).
 * @returns {{positions: Float32Array, faces: Uint32Array, vertexMap: Int32Array|null}}
 */
export function meshArrays(frame) {
  const nv = frame.header.n_vertices * 3;
  const nf = frame.header.n_faces * 3;
  const nm = (frame.header.file_vertices ?? 0) | 0;
  const positions = floatView(frame.payload, 0, nv);
  const start = frame.payload.byteOffset + 4 * nv;
  const faces = start % 4 === 0
    ? new Uint32Array(frame.payload.buffer, start, nf)
    : new Uint32Array(frame.payload.slice(4 * nv, 4 * (nv + nf)).buffer);
  // a copy: the map outlives the frame (constraints documents are read with it)
  const vertexMap = nm > 0 ? new Int32Array(frame.payload.slice(4 * (nv + nf), 4 * (nv + nf + nm)).buffer) : null;
  return { positions, faces, vertexMap };
}

/**
 * Positions of a `vertices` frame: of every vertex (a full frame, `subset` -1) or of the movable vertices only.
 * @param {{header: {subset: number, movable?: number}, payload: Uint8Array}} frame a `vertices` frame.
 * @returns {Float32Array}
 */
export function vertexArray(frame) {
  const movable = frame.header.subset < 0 ? ((frame.header.movable ?? 0) | 0) : 0;
  return floatView(frame.payload, 0, frame.payload.byteLength / 4 - movable);
}

/**
 * Movable vertices listed by a full `vertices` frame (a copy), or null when it lists none.
 * @param {{header: {subset: number, movable?: number}, payload: Uint8Array}} frame a `vertices` frame.
 * @returns {Uint32Array|null}
 */
export function movableArray(frame) {
  const k = frame.header.subset < 0 ? ((frame.header.movable ?? 0) | 0) : 0;
  if (k <= 0) return null;
  const start = frame.payload.byteLength - 4 * k;
  return new Uint32Array(frame.payload.slice(start, start + 4 * k).buffer);
}
