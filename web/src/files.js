// File input, drag and drop of meshes, downloads and constraint documents.
import { PARTNERS_KEY } from './mirror.js';
import { toMeshNumbering } from './numbering.js';
import { UPLOAD_EXTENSIONS } from './protocol.js';

export const MESH_EXTENSIONS = UPLOAD_EXTENSIONS.map((e) => e.replace(/^\./, '').toLowerCase());

/** @param {string|null|undefined} name */
export function extensionOf(name) {
  const m = /\.([^.]+)$/.exec(name || '');
  return m ? m[1].toLowerCase() : '';
}

/** @param {number} n */
export function formatBytes(n) {
  if (n >= 1024 * 1024) return `${(n / (1024 * 1024)).toFixed(1)} MB`;
  if (n >= 1024) return `${(n / 1024).toFixed(0)} KB`;
  return `${n} B`;
}

/**
 * Check a mesh file before upload; returns an error message or null.
 * @param {File} file
 * @param {number} maxBytes 0: no limit
 */
export function checkMeshFile(file, maxBytes) {
  const ext = extensionOf(file.name);
  if (!MESH_EXTENSIONS.includes(ext)) {
    return `"${file.name}" is neither a mesh file nor a picture the studio opens (use ${MESH_EXTENSIONS.map((e) => e.toUpperCase()).join(', ')}).`;
  }
  if (maxBytes && file.size > maxBytes) {
    return `"${file.name}" is too large: ${formatBytes(file.size)}, the limit is ${formatBytes(maxBytes)}.`;
  }
  return null;
}

/** Extensions of the mesh file among several files opened together (the others are what it names). */
const BUNDLE_MESH_EXTENSIONS = ['obj', 'ply', 'gltf', 'glb', 'off', 'stl'];

/** Extensions of the files a mesh file names, offered by the file picker beside the meshes. */
export const REFERENCED_EXTENSIONS = ['.mtl', '.bin', '.png', '.jpg', '.jpeg', '.webp', '.tga', '.bmp'];

const CRC_TABLE = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();

/** @param {Uint8Array} bytes */
function crc32(bytes) {
  let c = 0xffffffff;
  for (let k = 0; k < bytes.length; k++) c = CRC_TABLE[(c ^ bytes[k]) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/**
 * A zip archive (stored, not compressed) of files given by name and bytes.
 * @param {{name: string, bytes: Uint8Array}[]} files
 * @returns {Uint8Array<ArrayBuffer>}
 */
export function zipFiles(files) {
  const enc = new TextEncoder();
  /** @type {Uint8Array[]} */
  const parts = [];
  /** @type {Uint8Array[]} */
  const central = [];
  let offset = 0;
  for (const f of files) {
    const name = enc.encode(f.name);
    const crc = crc32(f.bytes);
    const head = new DataView(new ArrayBuffer(30));
    head.setUint32(0, 0x04034b50, true);
    head.setUint16(4, 20, true);
    head.setUint16(6, 0x0800, true); // UTF-8 names
    head.setUint32(14, crc, true);
    head.setUint32(18, f.bytes.length, true);
    head.setUint32(22, f.bytes.length, true);
    head.setUint16(26, name.length, true);
    const dir = new DataView(new ArrayBuffer(46));
    dir.setUint32(0, 0x02014b50, true);
    dir.setUint16(4, 20, true);
    dir.setUint16(6, 20, true);
    dir.setUint16(8, 0x0800, true);
    dir.setUint32(16, crc, true);
    dir.setUint32(20, f.bytes.length, true);
    dir.setUint32(24, f.bytes.length, true);
    dir.setUint16(28, name.length, true);
    dir.setUint32(42, offset, true);
    parts.push(new Uint8Array(head.buffer), name, f.bytes);
    central.push(new Uint8Array(dir.buffer), name);
    offset += 30 + name.length + f.bytes.length;
  }
  const size = central.reduce((n, c) => n + c.length, 0);
  const end = new DataView(new ArrayBuffer(22));
  end.setUint32(0, 0x06054b50, true);
  end.setUint16(8, files.length, true);
  end.setUint16(10, files.length, true);
  end.setUint32(12, size, true);
  end.setUint32(16, offset, true);
  const all = [...parts, ...central, new Uint8Array(end.buffer)];
  const out = new Uint8Array(all.reduce((n, c) => n + c.length, 0));
  let at = 0;
  for (const c of all) {
    out.set(c, at);
    at += c.length;
  }
  return out;
}

/**
 * Several files opened together (a mesh file and the MTL files, textures and buffers it names) as one zip named
 * after the mesh file, which the server reads as a bundle; one file as it is. Throws an Error (its message for the
 * status line) when the files hold no mesh file or several.
 * @param {File[]} files
 * @returns {Promise<File>}
 */
export async function bundleFiles(files) {
  if (files.length === 1) return files[0];
  const meshes = files.filter((f) => BUNDLE_MESH_EXTENSIONS.includes(extensionOf(f.name)));
  if (meshes.length !== 1) {
    throw new Error(meshes.length
      ? `Open one mesh file at a time with the files it names (${meshes.map((f) => f.name).join(', ')} were chosen together).`
      : `None of ${files.map((f) => f.name).join(', ')} is a mesh file (${BUNDLE_MESH_EXTENSIONS.map((e) => e.toUpperCase()).join(', ')}).`);
  }
  const entries = await Promise.all(files.map(async (f) => ({ name: f.name, bytes: new Uint8Array(await f.arrayBuffer()) })));
  const stem = meshes[0].name.replace(/\.[^.]+$/, '');
  return new File([zipFiles(entries)], `${stem}.zip`, { type: 'application/zip' });
}

/**
 * Save bytes (or a string) under a file name.
 * @param {Blob|BlobPart} data
 * @param {string} filename
 * @param {string} [mime]
 */
export function download(data, filename, mime = 'application/octet-stream') {
  const blob = data instanceof Blob ? data : new Blob([data], { type: mime });
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = filename;
  a.style.display = 'none';
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

/**
 * Download a constraints document as `<mesh name>-constraints.json`; returns the message to show.
 * @param {object} doc the document (any JSON object)
 * @param {string|null} meshName
 */
export function downloadConstraints(doc, meshName) {
  const base = (meshName || 'mesh').replace(/\.[^.]+$/, '');
  download(JSON.stringify(doc, null, 2), `${base}-constraints.json`, 'application/json');
  return 'Constraints saved.';
}

/**
 * Download an exported mesh (the server's export message with its binary frame); returns the message to show.
 * @param {(import('./protocol.js').ExportServerMessage|import('./protocol.js').AnimationServerMessage)
 *   & import('./messages.js').Framed} msg
 */
export function downloadExport(msg) {
  const p = msg.frame.payload;
  download(new Blob([p], { type: msg.mime || 'application/octet-stream' }), msg.filename || 'mesh');
  return `Exported ${msg.filename} (${formatBytes(p.byteLength)}).`;
}

/**
 * Route files dropped on `target` to onFile(files) (all of them: a mesh file may come with the files it names);
 * shows `overlay` while dragging files over it.
 * @param {HTMLElement} target
 * @param {HTMLElement} overlay
 * @param {(files: File[]) => void} onFile
 */
export function installDropTarget(target, overlay, onFile) {
  let depth = 0;
  const hasFiles = (/** @type {DragEvent} */ e) => Array.from(e.dataTransfer?.types || []).includes('Files');
  target.addEventListener('dragenter', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    depth++;
    overlay.hidden = false;
  });
  target.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    /** @type {DataTransfer} hasFiles saw it */ (e.dataTransfer).dropEffect = 'copy';
  });
  target.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) overlay.hidden = true;
  });
  target.addEventListener('drop', (e) => {
    e.preventDefault();
    depth = 0;
    overlay.hidden = true;
    const files = Array.from(e.dataTransfer?.files || []);
    if (files.length) onFile(files);
  });
  // a file dropped elsewhere must not navigate away from the studio
  window.addEventListener('dragover', (e) => e.preventDefault());
  window.addEventListener('drop', (e) => e.preventDefault());
}

/**
 * @param {unknown} v
 * @param {string} what
 * @returns {number[]}
 */
function indexList(v, what) {
  if (v === undefined || v === null) return [];
  if (!Array.isArray(v) || !v.every((i) => Number.isInteger(i) && i >= 0)) {
    throw new Error(`"${what}" must be a list of vertex indices`);
  }
  return v;
}

/**
 * @param {any} doc a parsed constraints document (JSON from a file: anything)
 * @returns {Map<number, number[]>|null}
 */
function targetMap(doc) {
  if (doc.targets === undefined || doc.targets === null) return null;
  const handles = indexList(doc.handles, 'handles');
  const t = doc.targets;
  if (!Array.isArray(t) || t.length !== handles.length) {
    throw new Error('"targets" must hold one [x, y, z] per entry of "handles"');
  }
  const map = new Map();
  t.forEach((p, k) => {
    if (!Array.isArray(p) || p.length !== 3 || !p.every((x) => typeof x === 'number' && Number.isFinite(x))) {
      throw new Error(`"targets[${k}]" must be three finite numbers`);
    }
    map.set(handles[k], p);
  });
  return map;
}

/** @type {(x: unknown) => x is number} */
const isNumber = (x) => typeof x === 'number' && Number.isFinite(x);
const isTriple = (/** @type {unknown} */ p) => Array.isArray(p) && p.length === 3 && p.every(isNumber);

/**
 * The point handles of a document (version 2): [{face, barycentric, weight?, target?, angle?, depth?}] (a picture's
 * pin: the angle in degrees it holds, its depth).
 * @param {any} doc a parsed constraints document (JSON from a file: anything)
 * @returns {{face: number, barycentric: number[], weight?: number, target?: number[], angle?: number,
 *   depth?: number}[]}
 */
function pointList(doc) {
  if (doc.points === undefined || doc.points === null) return [];
  if (!Array.isArray(doc.points)) throw new Error('"points" must be a list');
  return doc.points.map((/** @type {any} an entry of the JSON document */ p, /** @type {number} */ k) => {
    if (!p || typeof p !== 'object' || !Number.isInteger(p.face) || p.face < 0 || !isTriple(p.barycentric)) {
      throw new Error(`"points[${k}]" must have a triangle index "face" and three "barycentric" numbers`);
    }
    if (p.target !== undefined && !isTriple(p.target)) throw new Error(`"points[${k}].target" must be three numbers`);
    if (p.weight !== undefined && !(isNumber(p.weight) && p.weight > 0)) {
      throw new Error(`"points[${k}].weight" must be a positive number`);
    }
    if (p.angle !== undefined && p.angle !== null && !isNumber(p.angle)) {
      throw new Error(`"points[${k}].angle" must be a number of degrees`);
    }
    if (p.depth !== undefined && !Number.isInteger(p.depth)) throw new Error(`"points[${k}].depth" must be an integer`);
    /** @type {{face: number, barycentric: number[], weight?: number, target?: number[], angle?: number,
     *   depth?: number}} */
    const out = { face: p.face, barycentric: p.barycentric.slice() };
    if (p.weight !== undefined) out.weight = p.weight;
    if (p.target !== undefined) out.target = p.target.slice();
    if (isNumber(p.angle)) out.angle = p.angle;
    if (p.depth !== undefined) out.depth = p.depth;
    return out;
  });
}

const isStiffness = (/** @type {unknown} */ v) => v === 'rigid' || (isNumber(v) && v > 0);

/**
 * Painted stiffness of a document: [{vertices, value}] (a list of one value per vertex is turned into that). With
 * `nVertices`, checked as `arap deform` checks it: a value for each vertex, indices in range, no vertex given two
 * values.
 * @param {any} doc a parsed constraints document (JSON from a file: anything)
 * @param {number} [nVertices]
 * @returns {{vertices: number[], value: number|'rigid'}[]|null}
 */
function stiffnessList(doc, nVertices) {
  const s = doc.stiffness;
  if (s === undefined || s === null) return null;
  if (!Array.isArray(s)) throw new Error('"stiffness" must be a list');
  if (s.length && s.every((v) => v === null || typeof v !== 'object')) {
    if (nVertices !== undefined && s.length !== nVertices) {
      throw new Error(`"stiffness" lists one value per vertex: ${nVertices} expected, ${s.length} given`);
    }
    /** @type {Map<number|'rigid', number[]>} */
    const groups = new Map();
    s.forEach((/** @type {any} an entry of the JSON document */ v, /** @type {number} */ i) => {
      if (!isStiffness(v)) throw new Error(`"stiffness[${i}]" must be a positive number or "rigid"`);
      if (v === 1) return;
      if (!groups.has(v)) groups.set(v, []);
      /** @type {number[]} set just above */ (groups.get(v)).push(i);
    });
    return [...groups].map(([value, vertices]) => ({ vertices, value }));
  }
  /** @type {Set<number>} */
  const seen = new Set();
  return s.map((/** @type {any} an entry of the JSON document */ g, /** @type {number} */ k) => {
    const ok = g && typeof g === 'object' && isStiffness(g.value);
    if (!ok) throw new Error(`"stiffness[${k}]" must be {"vertices": [...], "value": a positive number or "rigid"}`);
    const vertices = indexList(g.vertices, `stiffness[${k}].vertices`);
    for (const i of vertices) {
      if (nVertices !== undefined && i >= nVertices) {
        throw new Error(`"stiffness[${k}].vertices" names vertex ${i}, but the mesh has ${nVertices} vertices`);
      }
      if (seen.has(i)) throw new Error(`vertex ${i} is given two stiffness values`);
      seen.add(i);
    }
    return { vertices, value: g.value };
  });
}

/**
 * Read a constraints document: the studio format {roi, fixed, handle_groups} or the command-line format
 * {fixed, handles, targets, roi, points, stiffness} (its handles become one group; point handles follow the groups,
 * painted stiffness comes as [{vertices, value}]). With `targets`, the result's `targets` maps each
 * handle vertex to its [x, y, z]; handles outside `handle_groups` (vertices a saved studio session held in place)
 * become one more group. `partners` lists the pairs [k, l] of mirror partner groups saved in "meta". With
 * `nVertices` (the mesh's), painted stiffness is checked against the mesh.
 * @param {string} text
 * @param {number} [nVertices]
 */
export function parseConstraints(text, nVertices = undefined) {
  let doc;
  try {
    doc = JSON.parse(text);
  } catch (err) {
    throw new Error(`not valid JSON (${errorText(err)})`);
  }
  if (!doc || typeof doc !== 'object' || Array.isArray(doc)) throw new Error('expected a JSON object');
  const roi = doc.roi === null || doc.roi === undefined ? null : indexList(doc.roi, 'roi');
  const fixed = indexList(doc.fixed, 'fixed');
  const targets = targetMap(doc);
  /** @type {number[][]} */
  let groups;
  if (Array.isArray(doc.handle_groups)) {
    groups = doc.handle_groups.map((/** @type {unknown} */ g, /** @type {number} */ k) => indexList(g, `handle_groups[${k}]`));
    if (targets) {
      const grouped = new Set(groups.flat());
      const missing = groups.flat().find((i) => !targets.has(i));
      if (missing !== undefined) throw new Error(`handle vertex ${missing} has no entry in "targets"`);
      const extra = [...targets.keys()].filter((i) => !grouped.has(i));
      if (extra.length) groups.push(extra);
    }
  } else if (doc.handles !== undefined) {
    const h = indexList(doc.handles, 'handles');
    groups = h.length ? [h] : [];
  } else {
    groups = [];
  }
  const points = pointList(doc);
  const stiffness = stiffnessList(doc, nVertices);
  if (!fixed.length && !groups.length && !points.length) {
    throw new Error('no "fixed" or handle vertices (or "points") in the document');
  }
  const partners = partnerPairs(doc, groups.length);
  return { roi: roi && roi.length ? roi : null, fixed, handle_groups: groups, targets, points, stiffness, partners };
}

/**
 * Read a constraints file (parseConstraints) and check it against the mesh; rejects with an Error whose message
 * names the file. Its indices are the mesh file's (as `arap deform` reads them): with `vertexMap` (the mesh vertex of
 * each file vertex when repair renumbered them, numbering.js) they are put into the mesh's numbering. Point handles
 * are refused on a mesh that repair changed (`repaired`), as `arap deform` refuses them: they name the file's
 * triangles.
 * @param {File} file
 * @param {number} nVertices
 * @param {number} nFaces
 * @param {Int32Array|null} vertexMap
 * @param {boolean} repaired
 */
export async function readConstraintsFile(file, nVertices, nFaces, vertexMap = null, repaired = false) {
  const text = await file.text();
  const nFile = vertexMap ? vertexMap.length : nVertices;
  let c;
  try {
    c = parseConstraints(text, nFile);
  } catch (err) {
    throw new Error(`Cannot read ${file.name}: ${errorText(err)}`);
  }
  const bad = [...(c.roi || []), ...c.fixed, ...c.handle_groups.flat()].find((i) => i >= nFile);
  if (bad !== undefined) {
    throw new Error(`${file.name} refers to vertex ${bad}, but the mesh ${vertexMap ? 'file ' : ''}has ${nFile} vertices.`);
  }
  if (c.points.length && repaired) {
    throw new Error(`Cannot load ${file.name}: its point handles refer to the file's triangles, which mesh repair `
      + 'changed (arap deform refuses them too); repair the mesh file first (arap info shows what repair changes).');
  }
  const badFace = c.points.find((p) => p.face >= nFaces);
  if (badFace) throw new Error(`${file.name} refers to triangle ${badFace.face}, but the mesh has ${nFaces} triangles.`);
  if (!vertexMap) return c;
  try {
    return toMeshNumbering(c, vertexMap, nVertices);
  } catch (err) {
    throw new Error(`Cannot load ${file.name}: ${errorText(err)}.`);
  }
}

/**
 * The mirror partners of handle groups saved in the document's "meta" (pairs [k, l] of groups; others skipped).
 * @param {any} doc a parsed constraints document (JSON from a file: anything)
 * @param {number} nGroups
 * @returns {[number, number][]}
 */
function partnerPairs(doc, nGroups) {
  const raw = doc.meta && typeof doc.meta === 'object' ? doc.meta[PARTNERS_KEY] : null;
  if (!Array.isArray(raw)) return [];
  const ok = (/** @type {any} an entry of the JSON document */ k) => Number.isInteger(k) && k >= 0 && k < nGroups;
  return raw.filter((p) => Array.isArray(p) && p.length === 2 && ok(p[0]) && ok(p[1]) && p[0] !== p[1]);
}

/**
 * The message of a caught error (anything may be thrown).
 * @param {unknown} err
 */
function errorText(err) {
  return err instanceof Error ? err.message : String(err);
}
