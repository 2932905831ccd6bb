// File input, drag and drop of meshes, downloads and constraint documents.
import { PARTNERS_KEY } from './mirror.js';
import { UPLOAD_EXTENSIONS } from './protocol.js';

export const MESH_EXTENSIONS = UPLOAD_EXTENSIONS.map((e) => e.replace(/^\./, '').toLowerCase());

export function extensionOf(name) {
  const m = /\.([^.]+)$/.exec(name || '');
  return m ? m[1].toLowerCase() : '';
}

export function formatBytes(n) {
  if (n >= 1024 * 1024) return `${(n / (1024 * 1024)).toFixed(1)} MB`;
  if (n >= 1024) return `${(n / 1024).toFixed(0)} KB`;
  return `${n} B`;
}

/** Check a mesh file before upload; returns an error message or null. */
export function checkMeshFile(file, maxBytes) {
  const ext = extensionOf(file.name);
  if (!MESH_EXTENSIONS.includes(ext)) {
    return `"${file.name}" is not a supported mesh file (use ${MESH_EXTENSIONS.map((e) => e.toUpperCase()).join(', ')}).`;
  }
  if (maxBytes && file.size > maxBytes) {
    return `"${file.name}" is too large: ${formatBytes(file.size)}, the limit is ${formatBytes(maxBytes)}.`;
  }
  return null;
}

/** Save bytes (or a string) under a file name. */
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

/** Route files dropped on `target` to onFile(file); shows `overlay` while dragging files over it. */
export function installDropTarget(target, overlay, onFile) {
  let depth = 0;
  const hasFiles = (e) => Array.from(e.dataTransfer?.types || []).includes('Files');
  target.addEventListener('dragenter', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    depth++;
    overlay.hidden = false;
  });
  target.addEventListener('dragover', (e) => {
    if (!hasFiles(e)) return;
    e.preventDefault();
    e.dataTransfer.dropEffect = 'copy';
  });
  target.addEventListener('dragleave', () => {
    depth = Math.max(0, depth - 1);
    if (depth === 0) overlay.hidden = true;
  });
  target.addEventListener('drop', (e) => {
    e.preventDefault();
    depth = 0;
    overlay.hidden = true;
    const file = e.dataTransfer?.files?.[0];
    if (file) onFile(file);
  });
  // a file dropped elsewhere must not navigate away from the studio
  window.addEventListener('dragover', (e) => e.preventDefault());
  window.addEventListener('drop', (e) => e.preventDefault());
}

function indexList(v, what) {
  if (v === undefined || v === null) return [];
  if (!Array.isArray(v) || !v.every((i) => Number.isInteger(i) && i >= 0)) {
    throw new Error(`"${what}" must be a list of vertex indices`);
  }
  return v;
}

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

/**
 * Read a constraints document: the studio format {roi, fixed, handle_groups} or the command-line format
 * {fixed, handles, targets, roi} (its handles become one group). With `targets`, the result's `targets` maps each
 * handle vertex to its [x, y, z]; handles outside `handle_groups` (vertices a saved studio session held in place)
 * become one more group. `partners` lists the pairs [k, l] of mirror partner groups saved in "meta".
 */
export function parseConstraints(text) {
  let doc;
  try {
    doc = JSON.parse(text);
  } catch (err) {
    throw new Error(`not valid JSON (${err.message})`);
  }
  if (!doc || typeof doc !== 'object' || Array.isArray(doc)) throw new Error('expected a JSON object');
  const roi = doc.roi === null || doc.roi === undefined ? null : indexList(doc.roi, 'roi');
  const fixed = indexList(doc.fixed, 'fixed');
  const targets = targetMap(doc);
  let groups;
  if (Array.isArray(doc.handle_groups)) {
    groups = doc.handle_groups.map((g, k) => indexList(g, `handle_groups[${k}]`));
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
  if (!fixed.length && !groups.length) throw new Error('no "fixed" or handle vertices in the document');
  return { roi: roi && roi.length ? roi : null, fixed, handle_groups: groups, targets, partners: partnerPairs(doc, groups.length) };
}

/** The mirror partners of handle groups saved in the document's "meta" (pairs [k, l] of groups; others skipped). */
function partnerPairs(doc, nGroups) {
  const raw = doc.meta && typeof doc.meta === 'object' ? doc.meta[PARTNERS_KEY] : null;
  if (!Array.isArray(raw)) return [];
  const ok = (k) => Number.isInteger(k) && k >= 0 && k < nGroups;
  return raw.filter((p) => Array.isArray(p) && p.length === 2 && ok(p[0]) && ok(p[1]) && p[0] !== p[1]);
}
