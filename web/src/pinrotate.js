// Alt-drag about a picture's pin (Photoshop's Puppet Warp gesture): with Alt held, a drag that starts near the active
// pin turns the picture about it. The pin first holds the angle its surroundings show (set_pin_angle), then the drag
// turns the pin's transform about the pin by the pointer's angle about it (in the picture's plane) and sends it as
// any drag does: the pin keeps its place and its hidden ring of points (the server's) turns with the transform.
import * as THREE from 'three';

/** How near the active pin (CSS pixels) an Alt-drag must start to turn it. */
export const TURN_RADIUS_PX = 150;

/**
 * The matrix that turns by `angle` radians about the z axis through `p`, then applies `start`'s transform first.
 * @param {THREE.Matrix4} start the pin's transform when the drag started
 * @param {THREE.Vector3} p the pin's place
 * @param {number} angle
 */
export function turnedAbout(start, p, angle) {
  const about = new THREE.Matrix4().makeTranslation(p.x, p.y, p.z)
    .multiply(new THREE.Matrix4().makeRotationZ(angle))
    .multiply(new THREE.Matrix4().makeTranslation(-p.x, -p.y, -p.z));
  return about.multiply(start);
}

/**
 * Wire the gesture on the viewer's canvas.
 * @param {{viewer: import('./viewer.js').Viewer, gizmo: import('./gizmo.js').HandleGizmo,
 *   picture: () => boolean, activePin: () => number|null,
 *   send: (m: import('./protocol.js').ClientMessage) => boolean}} deps
 */
export function installPinRotation({ viewer, gizmo, picture, activePin, send }) {
  const canvas = viewer.canvas;
  const frame = /** @type {HTMLElement} */ (canvas.parentElement);
  const raycaster = new THREE.Raycaster();
  /** @type {{id: number, pin: THREE.Vector3, start: THREE.Matrix4, from: number, group: number}|null} */
  let turning = null;

  /**
   * The pointer's angle about `p` in the plane z = p.z (null when the ray misses it).
   * @param {PointerEvent} e
   * @param {THREE.Vector3} p
   */
  function angleAbout(e, p) {
    const r = canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, 1 - ((e.clientY - r.top) / r.height) * 2);
    raycaster.setFromCamera(ndc, viewer.camera);
    const hit = raycaster.ray.intersectPlane(new THREE.Plane(new THREE.Vector3(0, 0, 1), -p.z), new THREE.Vector3());
    return hit ? Math.atan2(hit.y - p.y, hit.x - p.x) : null;
  }

  frame.addEventListener('pointerdown', (e) => {
    if (!e.altKey || e.button !== 0 || e.target !== canvas || !picture()) return;
    const k = activePin();
    if (k === null || gizmo.group < 0 || !gizmo.indices.length || !gizmo.matrices[gizmo.group]) return;
    const pin = new THREE.Vector3(...gizmo.centroid);
    const [x, y] = viewer.project(pin.toArray());
    const r = canvas.getBoundingClientRect();
    if (Math.hypot(e.clientX - r.left - x, e.clientY - r.top - y) > TURN_RADIUS_PX) return;
    const from = angleAbout(e, pin);
    if (from === null) return;
    e.preventDefault();
    e.stopPropagation(); // neither the orbit, the gizmo nor the pin tools see it
    if (gizmo.opts.onDragStart?.() === false) return;
    if (!send({ type: 'set_pin_angle', pin: k })) return; // the pin holds the angle it shows now
    turning = { id: e.pointerId, pin, start: gizmo.matrices[gizmo.group].clone(), from, group: gizmo.group };
    canvas.setPointerCapture?.(e.pointerId);
  }, { capture: true });

  frame.addEventListener('pointermove', (e) => {
    if (!turning || e.pointerId !== turning.id) return;
    e.stopPropagation();
    const now = angleAbout(e, turning.pin);
    const m = gizmo.matrices[turning.group];
    if (now === null || !m) return;
    m.copy(turnedAbout(turning.start, turning.pin, now - turning.from));
    gizmo.opts.onDrag();
    gizmo.recenter();
  }, { capture: true });

  /** @param {PointerEvent} e */
  const end = (e) => {
    if (!turning || e.pointerId !== turning.id) return;
    e.stopPropagation();
    turning = null;
    canvas.releasePointerCapture?.(e.pointerId);
    gizmo.opts.onDragEnd();
  };
  frame.addEventListener('pointerup', end, { capture: true });
  frame.addEventListener('pointercancel', end, { capture: true });
}
