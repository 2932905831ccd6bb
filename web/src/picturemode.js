// The controls of a picture opened for the puppet warp (the mesh message's `picture` is its [width, height]): the
// warp's mode, Rigid, Normal or Distort, as Photoshop's Puppet Warp offers them (set_params `warp`), and whether the
// mesh is drawn over the picture. They are hidden for a surface or a solid, which the mode does not concern. A picture
// opens in point handle mode, as Puppet Warp does: a click on the picture places a pin, the gizmo then moves it.
import { byId, byIdAs } from './dom.js';
import { PARAMS } from './protocol.js';

/** @type {((role: string) => void)|null} */
let chooseRole = null;

/**
 * Fill the Warp choice and wire the controls.
 * @param {{setParams: (p: {warp: "rigid"|"normal"|"distort"}) => void, setWireframe: (on: boolean) => void,
 *   setRole: (role: string) => void}} actions
 */
export function installPictureControls(actions) {
  chooseRole = actions.setRole;
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
}

/**
 * A new mesh: the picture controls show for a picture only.
 * @param {{picture?: number[]|null}} msg the mesh message
 */
export function pictureShown(msg) {
  const picture = Array.isArray(msg.picture) && msg.picture.length === 2;
  byId('picture-rows').hidden = !picture;
  byId('picture-size').textContent = picture ? `${msg.picture?.[0]} × ${msg.picture?.[1]} px` : '';
  byIdAs('picture-mesh', HTMLInputElement).checked = byIdAs('wireframe', HTMLInputElement).checked;
  if (picture) chooseRole?.('point'); // a click places a pin
}

/**
 * The server's parameters: the Warp choice shows its mode.
 * @param {{warp?: string}|null|undefined} p
 */
export function warpShown(p) {
  if (p?.warp) byIdAs('warp', HTMLSelectElement).value = p.warp;
}
