// Loading a constraints document chosen by the user: its selection replaces the page's, its handle targets move
// the handles there, and its keyframes (when it has them) go on the timeline, relative to the positions their
// transforms apply to.
import { readConstraintsFile } from './files.js';
import { EASINGS } from './keyframes.js';
import { restorePins } from './picturemode.js';
import { CLIENT } from './protocol.js';

/**
 * A constraints document with keyframes: the document whose handles start at the positions the keyframes' transforms
 * apply to (`keyframe_base`, else their rest positions in `rest`, the file's vertex i being mesh vertex
 * `vertexMap[i]`), and the keyframes in the timeline's form; null without keyframes. Throws when its keyframes
 * cannot be shown on the timeline.
 * @param {string} text
 * @param {ArrayLike<number>|null} rest (null: not known)
 * @param {Int32Array|null} vertexMap
 * @returns {{text: string, keys: {ms: number, transforms: number[][], easing: string}[], pins: number[][]}|null}
 *   (`pins`: the pivots of the point handles' transforms, after the handle groups', when the keyframes move them)
 */
export function keyframedDocument(text, rest, vertexMap) {
  let doc;
  try {
    doc = JSON.parse(text);
  } catch {
    return null; // readConstraintsFile says what is wrong
  }
  if (!doc || !Array.isArray(doc.keyframes) || !doc.keyframes.length || !Array.isArray(doc.handles)) return null;
  const readable = (/** @type {any} */ k) => Array.isArray(k?.transforms) && Number.isFinite(k.time) && k.time >= 0;
  if (!doc.keyframes.every(readable)) {
    throw new Error('the timeline shows keyframes of transforms at times from 0 s on; this document has others');
  }
  const base = Array.isArray(doc.keyframe_base) ? doc.keyframe_base : doc.handles.map((/** @type {number} */ i) => {
    const v = vertexMap ? vertexMap[i] : i;
    const r = /** @type {ArrayLike<number>} */ (rest);
    return [r[3 * v], r[3 * v + 1], r[3 * v + 2]];
  });
  // The point handles (a picture's pins) move with the keyframes too: the timeline holds one transform per pin after
  // the handle groups', from the pin's target in the document to its target at the keyframe, turned by the change of
  // the angle it holds (the points' "angle", then each keyframe's "point_angles").
  const points = Array.isArray(doc.points) ? doc.points : [];
  const groups = Array.isArray(doc.handle_groups) ? doc.handle_groups.length : 0;
  const pinned = points.length > 0 && points.every((/** @type {any} */ p) => Array.isArray(p?.target))
    && doc.keyframes.every((/** @type {any} */ k) => k.transforms.length === groups);
  /** @type {number[][]} */
  let held = points.map((/** @type {any} */ p) => p?.target);
  /** @type {(number|null)[]} */
  let angles = points.map((/** @type {any} */ p) => (Number.isFinite(p?.angle) ? p.angle : null));
  const keys = doc.keyframes.map((/** @type {any} */ k) => {
    const transforms = k.transforms.map((/** @type {any} */ m) => [0, 1, 2, 3].flatMap((c) => [0, 1, 2, 3]
      .map((r) => Number(m[r][c]))));
    if (pinned) {
      if (Array.isArray(k.point_targets) && k.point_targets.length === points.length) held = k.point_targets;
      if (Array.isArray(k.point_angles) && k.point_angles.length === points.length) angles = k.point_angles;
      points.forEach((/** @type {any} */ p, /** @type {number} */ j) => {
        const a = angles[j];
        const turn = Number.isFinite(p.angle) && typeof a === 'number' ? ((a - p.angle) * Math.PI) / 180 : 0;
        transforms.push(pinTransform(p.target, held[j], turn));
      });
    }
    return { ms: Math.round(1000 * k.time), transforms, easing: EASINGS.includes(k.easing) ? k.easing : 'linear' };
  });
  const pins = pinned ? points.map((/** @type {any} */ p) => p.target.map(Number)) : [];
  return { text: JSON.stringify({ ...doc, targets: base }), keys, pins };
}

/**
 * Column-major 4×4 that turns about z by `turn` (radians) about `from` and moves it to `to`.
 * @param {number[]} from @param {number[]} to @param {number} turn
 * @returns {number[]}
 */
function pinTransform(from, to, turn) {
  const c = Math.cos(turn);
  const s = Math.sin(turn);
  const [x, y, z] = from.map(Number);
  const [u, v, w] = to.map(Number);
  return [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, u - (c * x - s * y), v - (s * x + c * y), w - z, 1];
}

/**
 * What loading a document reads and changes.
 * @typedef {object} LoadDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/diagnostics.js').Diagnostics} diagnostics
 * @property {import('./viewer.js').Viewer} viewer
 * @property {import('./selection.js').Selection} selection
 * @property {import('./mirror.js').MirrorEditing} mirror
 * @property {import('./timeline.js').Timeline} timeline
 * @property {() => ArrayLike<number>|null} rest the rest pose of the mesh shown
 * @property {(full?: boolean) => void} refreshSelection
 * @property {(targets: Map<number, number[]>|null, force: boolean, pointTargets: (number[]|null)[]) => void} commit
 *   send the selection with its handle and point targets
 * @property {(text: string, kind: string) => void} say the status line
 */

/**
 * Load the constraints document `file`; what is wrong with it is said (and recorded as an error).
 * @param {File} file
 * @param {LoadDeps} d
 */
export function loadConstraintsFile(file, d) {
  file.text().then((text) => {
    const keyed = keyframedDocument(text, d.rest(), d.mesh.vertexMap);
    const read = keyed ? new File([keyed.text], file.name, { type: 'application/json' }) : file;
    return readConstraintsFile(read, d.viewer.nVertices, d.mesh.nFaces, d.mesh.vertexMap, d.mesh.repaired).then((c) => {
      d.selection.fromConstraints(c);
      d.mirror.setPairs(c.partners);
      d.refreshSelection(true);
      d.commit(c.targets, false, c.points.map((/** @type {any} */ p) => p.target ?? null));
      // a picture's pins: their depths and the angles they hold, after the pins themselves
      const points = /** @type {{angle?: number, depth?: number}[]} */ (c.points);
      if (points.some((p) => p.angle !== undefined || p.depth !== undefined)) {
        restorePins({ depth: points.some((p) => p.depth !== undefined) ? points.map((p) => p.depth ?? 0) : [],
          angles: points.map((p) => p.angle ?? null) });
      }
      if (keyed) {
        const targets = /** @type {Map<number, number[]>} */ (c.targets);
        const pivots = c.handle_groups.map((/** @type {number[]} */ g) => {
          const sum = [0, 0, 0];
          for (const i of g) /** @type {number[]} */ (targets.get(i)).forEach((x, k) => (sum[k] += x));
          return sum.map((x) => x / Math.max(g.length, 1));
        });
        d.timeline.load(keyed.keys, pivots.concat(keyed.pins));
      }
    });
  }).catch((err) => {
    d.diagnostics.error('client_check', err.message, CLIENT.SET_CONSTRAINTS);
    d.say(err.message, 'error');
  });
}
