// A snapshot of the editing session (what autosave stores and restoring puts back): where the mesh came from,
// the selection with every handle group, the current shape and the solver parameters.
import { inFileNumbering } from './numbering.js';
import { FIXED, HANDLE0 } from './selection.js';
import { stiffnessToJson } from './stiffness.js';

/**
 * Where the session's rest mesh comes from: a built-in model by name, or the bytes of a mesh file (an upload, or
 * the vertices and faces the server sent, written as PLY). `key` changes whenever the source does. `repaired`: the
 * bytes are a mesh that repair changed when its file was loaded (a PLY written from it loads without repairs, but
 * its triangles are still not the file's).
 */
let sourceKeys = 0;

/** @param {string} name */
export function builtinSource(name) {
  return { kind: 'builtin', name, key: ++sourceKeys };
}

/**
 * @param {string} filename
 * @param {ArrayBuffer|Uint8Array} bytes
 * @param {boolean} [repaired]
 */
export function fileSource(filename, bytes, repaired = false) {
  return { kind: 'file', filename, bytes, key: ++sourceKeys, repaired };
}

/** Extensions of the pictures the studio opens (meshed, for the puppet warp). */
const PICTURE_EXTENSIONS = ['png', 'jpg', 'jpeg', 'webp'];

/**
 * True when `source` is a picture file (a restore opens it again as a picture).
 * @param {{kind: string, filename?: string}|null} source
 */
export function isPictureSource(source) {
  const ext = String(source?.filename ?? '').split('.').pop()?.toLowerCase() ?? '';
  return source?.kind === 'file' && PICTURE_EXTENSIONS.includes(ext);
}

/**
 * The source of a picture (`picture`, a picture file's source) meshed at `density` (the server's `remesh`): a restore
 * opens the picture and meshes it again at that density.
 * @param {{filename?: string, bytes?: any}} picture
 * @param {string} density
 */
export function pictureSource(picture, density) {
  return { ...fileSource(String(picture.filename), picture.bytes), density };
}

/**
 * The export format (of the server's `export`) that keeps the look of a mesh from `source` (UVs, materials, textures,
 * vertex colours) and its file's vertex numbering, so that the file uploads again as the same mesh with the same
 * look: what the page keeps as the source once an apply made the shape the rest pose. A GLB stays a GLB and a PLY a
 * PLY; an OBJ (alone or in a zip with its MTL and textures) or a glTF comes back as an OBJ with its MTL and textures
 * (a zip). Null for a built-in model or any other source (a picture, an OFF or STL file: a PLY of the shape does).
 * @param {{kind: string, filename?: string}|null} source
 * @returns {'glb'|'ply'|'obj'|null}
 */
export function restExportFormat(source) {
  if (source?.kind !== 'file') return null;
  const ext = String(source.filename ?? '').split('.').pop()?.toLowerCase();
  if (ext === 'glb' || ext === 'ply') return ext;
  return ext === 'obj' || ext === 'gltf' || ext === 'zip' ? 'obj' : null;
}

/**
 * Binary little-endian PLY of a triangle mesh (float32 positions, uint32 faces). With `vertexMap` (the mesh vertex of
 * each vertex of the mesh file it came from, when repair renumbered them), in the file's numbering: uploaded again,
 * it is repaired into the same mesh with the same map (numbering.js inFileNumbering).
 * @param {ArrayLike<number>} positions
 * @param {ArrayLike<number>} faces
 * @param {Int32Array|null} vertexMap
 */
export function encodePly(positions, faces, vertexMap = null) {
  if (vertexMap) ({ positions, faces } = inFileNumbering(positions, faces, vertexMap));
  const nv = positions.length / 3;
  const nf = faces.length / 3;
  const header = new TextEncoder().encode(
    `ply\nformat binary_little_endian 1.0\nelement vertex ${nv}\nproperty float x\nproperty float y\n` +
      `property float z\nelement face ${nf}\nproperty list uchar uint vertex_indices\nend_header\n`,
  );
  const buf = new ArrayBuffer(header.length + 12 * nv + 13 * nf);
  new Uint8Array(buf).set(header);
  const view = new DataView(buf);
  let o = header.length;
  for (let i = 0; i < 3 * nv; i++, o += 4) view.setFloat32(o, positions[i], true);
  for (let f = 0; f < nf; f++) {
    view.setUint8(o, 3);
    o += 1;
    for (let k = 0; k < 3; k++, o += 4) view.setUint32(o, faces[3 * f + k], true);
  }
  return buf;
}

/**
 * What a snapshot takes from the page's stores besides the selection and the view.
 * @typedef {object} SessionFacts
 * @property {boolean} canUndo
 * @property {boolean} canRedo
 * @property {any} source where the mesh came from (builtinSource, fileSource)
 * @property {string|null} meshName
 * @property {number} nFaces
 * @property {{[name: string]: unknown}} params the solver parameters, by name
 */

/**
 * True when a session has something to lose: a selection, a deformation or history.
 * @param {{facts: SessionFacts, selection: import('./selection.js').Selection}} deps
 */
export function hasEdits({ facts, selection }) {
  if (facts.canUndo || facts.canRedo) return true;
  for (let i = 0; i < selection.n; i++) if (selection.role[i] || selection.roi[i] || selection.stiff[i] !== 1) return true;
  return selection.groups.some((g) => g.point);
}

/**
 * The session as a plain object (structured-cloneable): `source` (with its bytes), mesh counts, `roi`, `fixed`,
 * `groups` (one vertex list per client handle group, empty ones included), `groupPoints` (per group, its point
 * handle or null), `stiffness` (painted, as sent to the server, or null), `activeGroup`, `partners` (each group's
 * mirror partner, -1 for none), `pivots` (per group, its placed pivot as a world point of the current shape, or
 * null), `positions` (Float32Array of the current shape), `deformed` (the shape is not the rest pose `rest`, the
 * mesh as its source gives it; null when `rest` is not known) and `params`.
 * @param {{facts: SessionFacts, selection: import('./selection.js').Selection, viewer: import('./viewer.js').Viewer,
 *   gizmo?: import('./gizmo.js').HandleGizmo}} deps
 * @param {ArrayLike<number>|null} [rest]
 */
export function captureSession({ facts, selection, viewer, gizmo }, rest = null) {
  const groups = selection.groups.map(() => /** @type {number[]} */ ([]));
  /** @type {number[]} */
  const roi = [];
  /** @type {number[]} */
  const fixed = [];
  for (let i = 0; i < selection.n; i++) {
    if (selection.roi[i]) roi.push(i);
    const r = selection.role[i];
    if (r === FIXED) fixed.push(i);
    else if (r >= HANDLE0) groups[r - HANDLE0].push(i);
  }
  return {
    savedAt: Date.now(),
    source: facts.source,
    meshName: facts.meshName,
    nVertices: viewer.nVertices,
    nFaces: facts.nFaces,
    roi,
    fixed,
    groups,
    groupPoints: selection.groups.map((g) => (g.point ? { ...g.point, barycentric: g.point.barycentric.slice() } : null)),
    stiffness: stiffnessToJson(selection.stiff),
    activeGroup: selection.activeGroup,
    partners: selection.groups.map((_, g) => selection.partnerOf(g)),
    pivots: gizmo ? gizmo.placedPivots() : [],
    positions: new Float32Array(viewer.positions),
    deformed: rest && rest.length === viewer.positions.length ? moved(rest, viewer.positions) : null,
    params: { ...facts.params },
    edits: hasEdits({ facts, selection }),
  };
}

/**
 * True when some coordinate of `b` differs from `a`'s by more than a millionth of their extent.
 * @param {ArrayLike<number>} a
 * @param {ArrayLike<number>} b
 */
function moved(a, b) {
  let lo = Infinity;
  let hi = -Infinity;
  for (let i = 0; i < a.length; i++) {
    if (a[i] < lo) lo = a[i];
    if (a[i] > hi) hi = a[i];
  }
  const eps = 1e-6 * Math.max(hi - lo, 1e-30);
  for (let i = 0; i < a.length; i++) if (Math.abs(a[i] - b[i]) > eps) return true;
  return false;
}

/**
 * Why a snapshot does not fit a loaded mesh, or null.
 * @param {{nVertices: number, nFaces: number}} snap
 * @param {number} nVertices
 * @param {number} nFaces
 */
export function mismatch(snap, nVertices, nFaces) {
  if (snap.nVertices === nVertices && snap.nFaces === nFaces) return null;
  return `the mesh now has ${nVertices.toLocaleString('en-US')} vertices and ${nFaces.toLocaleString('en-US')} ` +
    `faces, the saved session had ${snap.nVertices.toLocaleString('en-US')} and ${snap.nFaces.toLocaleString('en-US')}`;
}

/**
 * What a snapshot holds, in a line or two: the mesh and whether its shape is deformed, the selection, and (with
 * `shown`, the name of the mesh the page shows now, when it is another) that restoring replaces that mesh.
 * @param {import('./autosave.js').Snapshot} snap
 * @param {string|null} [shown]
 */
export function describe(snap, shown = null) {
  const when = new Date(snap.savedAt).toLocaleString([], { dateStyle: 'medium', timeStyle: 'short' });
  const handles = snap.groups.filter((g) => g.length).length;
  const pointCount = (snap.groupPoints || []).filter((p) => p).length;
  const shape = snap.deformed === true ? ' (deformed)' : snap.deformed === false ? ' (shape as loaded)' : '';
  const parts = [`${snap.meshName}${shape}`];
  if (snap.roi.length) parts.push(`ROI of ${snap.roi.length.toLocaleString('en-US')} vertices`);
  parts.push(`${snap.fixed.length.toLocaleString('en-US')} anchors`);
  parts.push(`${handles} handle group${handles === 1 ? '' : 's'}`);
  if (pointCount) parts.push(`${pointCount} point handle${pointCount === 1 ? '' : 's'}`);
  if (snap.stiffness) parts.push('painted stiffness');
  const instead = shown && shown !== snap.meshName ? ` Restore loads ${snap.meshName} in place of the ${shown} shown.` : '';
  return `Unsaved work from ${when}: ${parts.join(', ')}.${instead}`;
}
