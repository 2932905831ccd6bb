// TransformControls whose rotate rings follow the pointer around the ring's centre, with snapping of rotations
// (15° steps) and of translations (a grid step) while a modifier is held or snapping is switched on. Where rings
// cross on screen, the ring nearest to the pointer is picked (not the one in front).
import * as THREE from 'three';
import { TransformControls } from 'three/addons/controls/TransformControls.js';
import { ROTATION_SNAP_DEG, snapTo, sweptAngle } from './transform.js';

const UNIT = { X: new THREE.Vector3(1, 0, 0), Y: new THREE.Vector3(0, 1, 0), Z: new THREE.Vector3(0, 0, 1) };
const _v = new THREE.Vector3();
const _q = new THREE.Quaternion();
/** @type {("X"|"Y"|"Z"|"E")[]} */
const RINGS = ['X', 'Y', 'Z', 'E'];
/** Points per ring when measuring how near the pointer is to it on screen. */
const RING_SAMPLES = 96;

/**
 * Rotation by the pointer: on an axis ring (X, Y, Z, in world or local axes) and on the view ring (E) the angle
 * is the one the pointer sweeps around the pivot's projection on screen (counter-clockwise on screen turns
 * counter-clockwise as seen from the camera); the free ball (XYZE) rolls like a trackball, one radian per ring
 * radius of pointer travel. Translation is TransformControls' own.
 */
/**
 * The state of a rotation under way: the axis (null: the free ball), the object's rotation when it began, the
 * pivot's and the pointer's last pixels, the angle swept so far and the free ball's accumulated roll.
 * @typedef {{worldAxis: THREE.Vector3|null, quaternion: THREE.Quaternion, centre: number[], last: number[],
 *   swept: number, roll: THREE.Quaternion}} RingDrag
 */

export class RingControls extends TransformControls {
  /**
   * @param {THREE.Camera} camera
   * @param {HTMLElement} canvas
   */
  constructor(camera, canvas) {
    super(camera, canvas);
    this.canvas = canvas; // the element the pointer moves over (domElement, which Controls types as nullable)
    this.snapAlways = false; // snapping switched on in the panel
    this.snapKey = false; // the modifier (Ctrl or ⌘) held during the drag
    this.gridStep = 0; // translation snap step (model units)
    this._muted = false;
    /** @type {RingDrag|null} state of the rotation under way */
    this._ring = null;
    /** @type {PointerEvent|null} */
    this._lastPointer = null; // the latest pointer of the drag (re-applied when the modifier changes)
    const track = (/** @type {PointerEvent|KeyboardEvent} */ e) => {
      const held = e.ctrlKey || e.metaKey;
      if (held === this.snapKey) return;
      this.snapKey = held;
      if (this.dragging && this._lastPointer) this.pointerMove(this._lastPointer); // snap (or not) at once
    };
    // capture on the window: seen before the controls' own pointer handlers on the canvas
    for (const type of /** @type {const} */ (['pointerdown', 'pointermove', 'keydown', 'keyup'])) window.addEventListener(type, track, true);
  }

  /** TransformControls' internal state (the drag's start, the pivot's and the camera's world pose). */
  get tc() {
    return /** @type {any} */ (this);
  }

  /** True while moves snap (modifier held, or snapping switched on). */
  get snapping() {
    return this.snapAlways || this.snapKey;
  }

  /**
   * @template {Extract<keyof import('three/addons/controls/TransformControls.js').TransformControlsEventMap, string>} T
   * @param {THREE.BaseEvent<T> & import('three/addons/controls/TransformControls.js').TransformControlsEventMap[T]} event
   */
  dispatchEvent(event) {
    if (!this._muted) super.dispatchEvent(event);
  }

  /**
   * Pixel coordinates (relative to the canvas) of a pointer in normalised device coordinates.
   * @param {{x: number, y: number}} pointer
   * @returns {number[]}
   */
  _pixels(pointer) {
    const r = this.canvas.getBoundingClientRect();
    return [((pointer.x + 1) / 2) * r.width, ((1 - pointer.y) / 2) * r.height];
  }

  _centrePixels() {
    const v = _v.copy(this.tc.worldPosition).project(this.camera);
    return this._pixels(v);
  }

  /**
   * TransformControls picks the first picker the pointer's ray meets: where two rings cross on screen, the one in
   * front, even with the pointer on the other ring's line. Of the rings, the one whose line passes nearest to the
   * pointer on screen is picked instead.
   * @param {PointerEvent|null} pointer (TransformControls' pointer: x, y in normalised device coordinates)
   */
  pointerHover(pointer) {
    super.pointerHover(pointer);
    if (this.mode !== 'rotate' || this.object === undefined || this.dragging || pointer === null) return;
    const picked = RINGS.find((name) => name === this.axis);
    if (!picked) return;
    const at = this._pixels(pointer);
    let best = picked;
    let bestD = this._ringDistance(best, at);
    for (const name of RINGS) {
      if (name === best) continue;
      const d = this._ringDistance(name, at);
      if (d < bestD) {
        best = name;
        bestD = d;
      }
    }
    this.axis = best;
  }

  /**
   * Distance on screen (pixels) from `at` to the line of ring `name` (X, Y, Z: radius 0.5; E: 0.75).
   * @param {"X"|"Y"|"Z"|"E"} name
   * @param {number[]} at
   */
  _ringDistance(name, at) {
    let axis;
    if (name === 'E') axis = this.tc.eye.clone();
    else {
      axis = UNIT[name].clone();
      if (this.space === 'local') axis.applyQuaternion(this.tc.worldQuaternion);
    }
    const radius = (name === 'E' ? 0.75 : 0.5) * this.handleScale();
    const u = Math.abs(axis.x) < 0.9 ? new THREE.Vector3(1, 0, 0) : new THREE.Vector3(0, 1, 0);
    u.sub(axis.clone().multiplyScalar(u.dot(axis))).normalize();
    const w = axis.clone().cross(u);
    const centre = this.tc.worldPosition;
    let best = Infinity;
    let prev = null;
    for (let k = 0; k <= RING_SAMPLES; k++) {
      const phi = (2 * Math.PI * k) / RING_SAMPLES;
      _v.copy(centre).addScaledVector(u, radius * Math.cos(phi)).addScaledVector(w, radius * Math.sin(phi));
      const p = this._pixels(_v.project(this.camera));
      if (prev) best = Math.min(best, segmentDistance(at, prev, p));
      prev = p;
    }
    return best;
  }

  /** @param {PointerEvent|null} pointer */
  pointerDown(pointer) {
    super.pointerDown(pointer);
    this._ring = null;
    if (!this.dragging || this.mode !== 'rotate' || pointer === null) return;
    const axis = this.axis;
    let worldAxis = null;
    if (axis === 'X' || axis === 'Y' || axis === 'Z') {
      worldAxis = UNIT[axis].clone();
      if (this.space === 'local') worldAxis.applyQuaternion(this.tc.worldQuaternion);
    } else if (axis === 'E') {
      worldAxis = this.tc.eye.clone();
    }
    const start = this._pixels(pointer);
    this._ring = {
      worldAxis, // null: the free ball
      quaternion: this.object.quaternion.clone(),
      centre: this._centrePixels(),
      last: start,
      swept: 0, // unwrapped angle swept on screen (radians, counter-clockwise positive)
      roll: new THREE.Quaternion(), // free ball: rotation accumulated so far
    };
  }

  /** @param {PointerEvent|null} pointer */
  pointerMove(pointer) {
    if (pointer !== null) this._lastPointer = pointer;
    if (this.mode === 'rotate' && this._ring && this.dragging && pointer !== null) {
      this._rotate(pointer, this._ring);
      return;
    }
    if (this.mode !== 'translate' || !this.snapping || !(this.gridStep > 0)) {
      super.pointerMove(pointer);
      return;
    }
    this._muted = true;
    try {
      super.pointerMove(pointer);
    } finally {
      this._muted = false;
    }
    if (!this.dragging || this.object === undefined) return;
    this._snapTranslation();
    this.dispatchEvent({ type: 'change' });
    this.dispatchEvent({ type: 'objectChange' });
  }

  /** Round the move since the drag began to the grid, along the axes shown (world or local). */
  _snapTranslation() {
    const offset = _v.copy(this.object.position).sub(this.tc._positionStart);
    const local = this.space === 'local' && this.axis !== 'XYZ';
    if (local) offset.applyQuaternion(_q.copy(this.tc._quaternionStart).invert());
    offset.set(snapTo(offset.x, this.gridStep), snapTo(offset.y, this.gridStep), snapTo(offset.z, this.gridStep));
    if (local) offset.applyQuaternion(this.tc._quaternionStart);
    this.object.position.copy(this.tc._positionStart).add(offset);
  }

  /**
   * @param {PointerEvent} pointer
   * @param {RingDrag} ring the rotation under way
   */
  _rotate(pointer, ring) {
    const at = this._pixels(pointer);
    if (pointer.button !== -1 && pointer.button !== undefined) return;
    if (ring.worldAxis) {
      ring.swept += sweptAngle(ring.centre, ring.last, at);
      ring.last = at;
      let angle = ring.swept * (ring.worldAxis.dot(this.tc.eye) < 0 ? -1 : 1);
      if (this.snapping) angle = snapTo(angle, THREE.MathUtils.degToRad(ROTATION_SNAP_DEG));
      this.tc.rotationAxis.copy(ring.worldAxis);
      this.tc.rotationAngle = angle;
      this.object.quaternion.setFromAxisAngle(ring.worldAxis, angle).multiply(ring.quaternion).normalize();
    } else {
      const dx = at[0] - ring.last[0];
      const dy = ring.last[1] - at[1];
      ring.last = at;
      const travel = Math.hypot(dx, dy);
      if (travel === 0) return;
      const radius = Math.max(8, Math.hypot(...this._ringOffsetPixels(ring.centre)));
      // the screen motion in world terms, and the axis that rolls the front of the ball that way
      const right = _v.set(1, 0, 0).applyQuaternion(this.tc.cameraQuaternion).multiplyScalar(dx);
      const motion = new THREE.Vector3(0, 1, 0).applyQuaternion(this.tc.cameraQuaternion).multiplyScalar(dy).add(right);
      const axis = new THREE.Vector3().crossVectors(this.tc.eye, motion).normalize();
      ring.roll.premultiply(_q.setFromAxisAngle(axis, travel / radius));
      this.tc.rotationAxis.copy(axis);
      this.tc.rotationAngle = travel / radius;
      this.object.quaternion.copy(ring.roll).multiply(ring.quaternion).normalize();
    }
    this.dispatchEvent({ type: 'change' });
    this.dispatchEvent({ type: 'objectChange' });
  }

  /** What the drag under way has done so far: 'Rotate Z: 45°', 'Move X: 0.05', or '' when none is under way. */
  dragText() {
    if (!this.dragging || this.object === undefined || this.axis === null) return '';
    const axis = this.axis === 'E' ? 'view axis' : this.axis === 'XYZE' ? 'free' : this.axis;
    if (this.mode === 'rotate') {
      const q = this.object.quaternion.clone().multiply(this.tc._quaternionStart.clone().invert());
      const turned = this._ring?.worldAxis ? this.tc.rotationAngle : 2 * Math.acos(Math.min(1, Math.abs(q.w)));
      return `Rotate ${axis}: ${Number(THREE.MathUtils.radToDeg(turned).toFixed(1))}°`;
    }
    const d = this.object.position.clone().sub(this.tc._positionStart);
    if (this.space === 'local' && this.axis !== 'XYZ') d.applyQuaternion(this.tc._quaternionStart.clone().invert());
    const shown = this.axis;
    const parts = /** @type {('x'|'y'|'z')[]} */ (['x', 'y', 'z']).filter((c) => shown.includes(c.toUpperCase()));
    return `Move ${shown}: ${parts.map((c) => Number(d[c].toPrecision(4))).join(', ')}`;
  }

  /** World size of the gizmo's unit (its handles keep a constant screen size; TransformControls' own factor). */
  handleScale() {
    const cam = /** @type {THREE.PerspectiveCamera} */ (this.camera);
    const d = this.tc.worldPosition.distanceTo(this.tc.cameraPosition);
    return (d * Math.min((1.9 * Math.tan((Math.PI * cam.fov) / 360)) / cam.zoom, 7) * this.size) / 4;
  }

  /**
   * Screen offset (pixels) from the centre to a point of an axis ring (radius 0.5 of the gizmo's size).
   * @param {number[]} centre
   * @returns {[number, number]}
   */
  _ringOffsetPixels(centre) {
    const scale = this.handleScale();
    const up = _v.set(0, 1, 0).applyQuaternion(this.tc.cameraQuaternion).multiplyScalar(0.5 * scale);
    const p = this._pixels(up.add(this.tc.worldPosition).project(this.camera));
    return [p[0] - centre[0], p[1] - centre[1]];
  }
}

/**
 * Distance from point p to the segment a–b (2D).
 * @param {number[]} p
 * @param {number[]} a
 * @param {number[]} b
 */
function segmentDistance(p, a, b) {
  const dx = b[0] - a[0];
  const dy = b[1] - a[1];
  const len2 = dx * dx + dy * dy;
  const t = len2 > 0 ? Math.max(0, Math.min(1, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2)) : 0;
  return Math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy);
}
