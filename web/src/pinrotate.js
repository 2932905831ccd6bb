// Alt-drag about a picture's pin (Photoshop's Puppet Warp gesture): with Alt held, a drag that starts near the active
// pin turns the picture about it. The pin first holds the angle its surroundings show (set_pin_angle), then the drag
// turns the pin's transform about the pin by the pointer's angle about it (in the picture's plane) and sends it as
// any drag does: the pin keeps its place and its hidden ring of points (the server's) turns with the transform.
// While Alt is held with the pointer within reach of the active pin, the gesture is armed and says so: a rotate
// cursor, and a ring about the pin; both go when Alt is released or the pointer leaves the reach (or the view).
import * as THREE from 'three';

/** How near the active pin (CSS pixels) an Alt-drag must start to turn it. */
export const TURN_RADIUS_PX = 150;
/** Radius (CSS pixels) of the ring drawn about the active pin while the gesture is armed. */
export const ARMED_RING_PX = 22;
/** The cursor while the gesture is armed: a circular arrow (a turn), else the browser's "alias". */
export const TURN_CURSOR = 'url("data:image/svg+xml,' + encodeURIComponent(
  '<svg xmlns="http://www.w3.org/2000/svg" width="24" height="24" viewBox="0 0 24 24" fill="none" '
  + 'stroke-linecap="round" stroke-linejoin="round"><g stroke="white" stroke-width="4">'
  + '<path d="M19 12a7 7 0 1 1-2.05-4.95"/><path d="M17.5 3.5v4h-4"/></g><g stroke="black" stroke-width="2">'
  + '<path d="M19 12a7 7 0 1 1-2.05-4.95"/><path d="M17.5 3.5v4h-4"/></g></svg>') + '") 12 12, alias';

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
  /** @type {{id: number, pin: THREE.Vector3, start: THREE.Matrix4, from: number, group: number, x: number,
   *   y: number}|null} */
  let turning = null;
  /** @type {{x: number, y: number}|null} the pointer's last place over the view (client pixels) */
  let pointer = null;
  let altHeld = false;
  const ring = document.createElement('div');
  ring.id = 'pin-turn-ring';
  ring.dataset.testid = 'pin-turn-ring';
  ring.hidden = true;
  Object.assign(ring.style, {
    position: 'absolute', width: `${2 * ARMED_RING_PX}px`, height: `${2 * ARMED_RING_PX}px`, borderRadius: '50%',
    border: '2px solid #ffd24a', boxShadow: '0 0 0 1px rgba(0, 0, 0, 0.6)', pointerEvents: 'none',
    transform: 'translate(-50%, -50%)',
  });
  frame.appendChild(ring);

  /**
   * The active pin's place on the screen (CSS pixels from the canvas's corner) when a turn can start from the
   * client point (x, y) (within reach), else null.
   * @param {number} x
   * @param {number} y
   */
  function armedAt(x, y) {
    if (!picture() || activePin() === null || gizmo.group < 0 || !gizmo.indices.length) return null;
    if (!gizmo.matrices[gizmo.group]) return null;
    const [px, py] = viewer.project(gizmo.centroid);
    const r = canvas.getBoundingClientRect();
    return Math.hypot(x - r.left - px, y - r.top - py) <= TURN_RADIUS_PX ? { px, py } : null;
  }

  /** Show the armed gesture (cursor and ring) or take it away, as Alt, the pointer and the pin now stand. */
  function showArmed() {
    const at = turning ? armedAt(turning.x, turning.y) : altHeld && pointer ? armedAt(pointer.x, pointer.y) : null;
    ring.hidden = !at;
    canvas.style.cursor = at ? TURN_CURSOR : '';
    if (!at) return;
    ring.style.left = `${canvas.offsetLeft + at.px}px`;
    ring.style.top = `${canvas.offsetTop + at.py}px`;
  }

  frame.addEventListener('pointermove', (e) => {
    pointer = { x: e.clientX, y: e.clientY };
    altHeld = e.altKey;
    showArmed();
  });
  frame.addEventListener('pointerleave', () => {
    pointer = null;
    showArmed();
  });
  window.addEventListener('keydown', (e) => {
    if (e.key !== 'Alt') return;
    altHeld = true;
    showArmed();
  });
  window.addEventListener('keyup', (e) => {
    if (e.key !== 'Alt') return;
    altHeld = false;
    showArmed();
  });
  window.addEventListener('blur', () => {
    altHeld = false;
    showArmed();
  });

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
    turning = { id: e.pointerId, pin, start: gizmo.matrices[gizmo.group].clone(), from, group: gizmo.group,
      x: e.clientX, y: e.clientY };
    canvas.setPointerCapture?.(e.pointerId);
  }, { capture: true });

  frame.addEventListener('pointermove', (e) => {
    if (!turning || e.pointerId !== turning.id) return;
    e.stopPropagation();
    const now = angleAbout(e, turning.pin);
    if (now === null || !gizmo.matrices[turning.group]) return;
    gizmo.setMatrix(turning.group, turnedAbout(turning.start, turning.pin, now - turning.from));
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
    showArmed();
  };
  frame.addEventListener('pointerup', end, { capture: true });
  frame.addEventListener('pointercancel', end, { capture: true });
}
