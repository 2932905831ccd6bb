// The controls of a picture opened for the puppet warp (the mesh message's `picture` is its [width, height]): the
// warp's mode, Rigid, Normal or Distort, as Photoshop's Puppet Warp offers them (set_params `warp`), and whether the
// mesh is drawn over the picture. They are hidden for a surface or a solid, which the mode does not concern. A picture
// opens in point handle mode, as Puppet Warp does: a click on the picture places a pin, the gizmo then moves it.
import { addSnapshotPart } from './autosave.js';
import { byId, byIdAs } from './dom.js';
import { PARAMS } from './protocol.js';
import { onSessionRestored } from './restore.js';

/** @type {((role: string) => void)|null} */
let chooseRole = null;
/** The depth of each pin (point handle, in their order) as last sent: set_pin_depth. @type {number[]} */
let depth = [];
/** Whether the next mesh is the picture meshed again (its pins and their depths kept). */
let remeshing = false;
/** Whether the mesh shown is a picture's. */
let shownPicture = false;
/** Per pin, the angle (degrees) it holds as the last state said, or null (it turns freely). @type {(number|null)[]} */
let angles = [];
/** The first triangle of the drawing order the last state gave (null: the mesh's order). @type {number|null} */
let drawFirst = null;

/** How the picture controls send a message (installPictureControls). @type {((m: any) => void)|null} */
let sendPinMessage = null;

/**
 * Give the pins of the picture shown their depths and angles again (a restored session's `pins`, a loaded
 * document's pins): set_pin_depth, then set_pin_angle for each pin that holds an angle (one undo step). Nothing for
 * a mesh that is not a picture's.
 * @param {{depth?: unknown, angles?: unknown}|undefined|null} pins per pin, its depth (integers) and its angle
 *   (degrees or null)
 */
export function restorePins(pins) {
  const send = sendPinMessage;
  if (!shownPicture || !pins || !send) return;
  if (Array.isArray(pins.depth) && pins.depth.length && pins.depth.every(Number.isInteger)) {
    depth = /** @type {number[]} */ (pins.depth).slice();
    send({ type: 'set_pin_depth', depth });
  }
  if (!Array.isArray(pins.angles)) return;
  const held = pins.angles.map((a, k) => [k, a]).filter(([, a]) => typeof a === 'number' && Number.isFinite(a));
  for (const [pin, angle] of held) send({ type: 'set_pin_angle', pin, angle });
  if (held.length) send({ type: 'end_drag' }); // one undo step
}

/** True when the mesh shown is a picture's (its pins can be turned, pinrotate.js). */
export function isPicture() {
  return shownPicture;
}

/**
 * The pins' depths with pin `k` moved to the front (`forward`) or the back, as ranks 0, 1, ... (larger: in front).
 * @param {number[]} given the depths as last sent (pins beyond them: 0)
 * @param {number} k
 * @param {boolean} forward
 * @returns {number[]}
 */
export function movedDepth(given, k, forward) {
  const d = Array.from({ length: Math.max(given.length, k + 1) }, (_, j) => given[j] ?? 0);
  d[k] = forward ? Math.max(...d) + 1 : Math.min(...d) - 1;
  const order = d.map((_, j) => j).sort((a, b) => d[a] - d[b] || a - b);
  const ranks = new Array(d.length).fill(0);
  order.forEach((j, r) => (ranks[j] = r));
  return ranks;
}

/**
 * Fill the Warp choice and wire the controls.
 * @param {{setParams: (p: {warp: "rigid"|"normal"|"distort"}) => void, setWireframe: (on: boolean) => void,
 *   setRole: (role: string) => void, activePin: () => number|null,
 *   send: (m: import('./protocol.js').ClientMessage) => void}} actions
 */
export function installPictureControls(actions) {
  chooseRole = actions.setRole;
  // a saved session keeps the pins' depths and angles, and restoring sends them again
  addSnapshotPart('pins', () => (shownPicture && (depth.length || angles.some((a) => a !== null))
    ? { depth: depth.slice(), angles: angles.slice() } : null));
  sendPinMessage = actions.send;
  onSessionRestored((snap) => {
    restorePins(/** @type {{depth?: unknown, angles?: unknown}|undefined} */ (snap.pins));
    // a picture meshed again at another density comes back so meshed (restore.js): the control shows it
    const density = snap.source?.density;
    if (shownPicture && typeof density === 'string') byIdAs('density', HTMLSelectElement).value = density;
  });
  const select = byIdAs('warp', HTMLSelectElement);
  select.innerHTML = '';
  for (const value of PARAMS.warp.choices) {
    const o = document.createElement('option');
    o.value = value;
    o.textContent = /** @type {Record<string, string>} */ (PARAMS.warp.labels)[value] ?? value;
    select.appendChild(o);
  }
  select.value = PARAMS.warp.default;
  select.addEventListener('change', () => actions.setParams({
    warp: /** @type {"rigid"|"normal"|"distort"} */ (select.value) }));
  const mesh = byIdAs('picture-mesh', HTMLInputElement);
  mesh.addEventListener('change', () => {
    byIdAs('wireframe', HTMLInputElement).checked = mesh.checked; // the Display section's control says the same
    actions.setWireframe(mesh.checked);
  });
  for (const [id, forward] of /** @type {[string, boolean][]} */ ([['pin-forward', true], ['pin-backward', false]])) {
    byId(id).addEventListener('click', () => {
      const k = actions.activePin();
      if (k === null) return;
      depth = movedDepth(depth, k, forward);
      actions.send({ type: 'set_pin_depth', depth });
    });
  }
  const density = byIdAs('density', HTMLSelectElement);
  density.addEventListener('change', () => {
    remeshing = true;
    actions.send({ type: 'remesh', density: /** @type {"coarse"|"normal"|"fine"} */ (density.value) });
  });
}

/**
 * A new mesh: the picture controls show for a picture only.
 * @param {{picture?: number[]|null}} msg the mesh message
 */
export function pictureShown(msg) {
  const picture = Array.isArray(msg.picture) && msg.picture.length === 2;
  shownPicture = picture;
  byId('picture-rows').hidden = !picture;
  byId('picture-size').textContent = picture ? `${msg.picture?.[0]} × ${msg.picture?.[1]} px` : '';
  byIdAs('picture-mesh', HTMLInputElement).checked = byIdAs('wireframe', HTMLInputElement).checked;
  if (picture) chooseRole?.('point'); // a click places a pin
  if (!remeshing) {
    depth = [];
    byIdAs('density', HTMLSelectElement).value = 'normal';
  }
  remeshing = false;
}

/**
 * A state: the angles the picture's pins hold, and the order in which its triangles are drawn (their pins' depths)
 * with its layers (the wireframe overlay follows them).
 * @param {{constraints?: {points?: {angle?: number}[]}, draw_order?: number[]|null, draw_layers?: number[]|null}} msg
 * @param {import('./viewer.js').Viewer} viewer
 */
export function pinsStated(msg, viewer) {
  angles = (msg.constraints?.points ?? []).map((p) => (typeof p.angle === 'number' ? p.angle : null));
  drawFirst = msg.draw_order?.[0] ?? null;
  viewer.drawOrder(msg.draw_order, msg.draw_layers); // in every surface view (texture, colours, plain, the heat map)
}

/** The pins' depths as last sent, their angles and the first triangle drawn as last stated (the test hook's view). */
export function picturePins() {
  return { depth: depth.slice(), angles: angles.slice(), drawFirst };
}

/**
 * The server's parameters: the Warp choice shows its mode.
 * @param {{warp?: string}|null|undefined} p
 */
export function warpShown(p) {
  if (p?.warp) byIdAs('warp', HTMLSelectElement).value = p.warp;
}
