// Exact transforms typed in, as in Blender: G (move) or R (rotate), an axis letter, the amount, Enter. The gizmo
// shows the result while it is typed; Enter sends it as one drag (drag, then end_drag), Escape drops it.
import * as THREE from 'three';
import { rotationAbout, translationBy } from './transform.js';

const VERB = { translate: 'Move', rotate: 'Rotate' };

/**
 * A typed transform under way: what it does, along which axis (null: not typed yet), the amount typed so far, the
 * group it was started on, and the key last refused (or null).
 * @typedef {{mode: 'translate'|'rotate', axis: 'x'|'y'|'z'|null, text: string, group: number,
 *   refused: string|null}} Entry
 */

/**
 * The number typed so far ('' and lone signs or points count as 0; an unfinished exponent as none).
 * @param {string} text
 */
export function typedValue(text) {
  const v = Number.parseFloat(text);
  return Number.isFinite(v) ? v : 0;
}

/**
 * The text typed so far after one more key (a digit, '.', '-' or 'e'), or null when the key cannot go there: a
 * number in exponent notation ('1e3', '-2.5e-2'); '-' toggles the sign of the exponent right after 'e', else the
 * number's.
 * @param {string} text @param {string} key
 * @returns {string|null}
 */
export function typedText(text, key) {
  const e = text.search(/e/i);
  if (/^[0-9]$/.test(key)) return text + key;
  if (key === '.') return text.includes('.') || e >= 0 ? null : text + key;
  if (key === 'e' || key === 'E') return e >= 0 || !/[0-9]/.test(text) ? null : `${text}e`;
  if (key === '-') {
    if (text.endsWith('e')) return `${text}-`;
    if (text.endsWith('e-')) return text.slice(0, -1);
    return text.startsWith('-') ? text.slice(1) : `-${text}`;
  }
  return null;
}

/**
 * The active group's whole transform after moving it by `amount` model units along `axis` ('x', 'y', 'z'), or
 * rotating it by `amount` degrees about the axis through the pivot ('view': the axis towards the camera).
 * @param {import('./gizmo.js').HandleGizmo} gizmo @param {THREE.Camera} camera
 * @param {string} mode 'translate' or 'rotate'
 * @param {string} axis 'x', 'y', 'z' or 'view'
 * @param {number} amount model units or degrees
 * @returns {THREE.Matrix4|null} null when no group is active
 */
export function typedTransform(gizmo, camera, mode, axis, amount) {
  const m = gizmo.matrices[gizmo.group];
  if (!m || !gizmo.indices.length) return null;
  const pivot = new THREE.Vector3().fromArray(gizmo.pivotWorld);
  let dir;
  if (axis === 'view') dir = camera.getWorldPosition(new THREE.Vector3()).sub(pivot).normalize();
  else dir = gizmo.axisVector(axis);
  if (mode === 'rotate') return rotationAbout(pivot, dir, THREE.MathUtils.degToRad(amount), m);
  return translationBy(dir.multiplyScalar(amount), m);
}

export class NumericEntry {
  /**
   * @param {{gizmo: import('./gizmo.js').HandleGizmo, viewer: import('./viewer.js').Viewer, line: HTMLElement,
   *   canStart: () => boolean}} opts line: the element showing what is typed; canStart(): true when a handle group
   *   is active and the studio is ready
   */
  constructor({ gizmo, viewer, line, canStart }) {
    this.gizmo = gizmo;
    this.viewer = viewer;
    this.line = line;
    this.canStart = canStart;
    /** @type {Entry|null} */
    this.entry = null;
    this.pointerOver = false;
    const c = viewer.canvas;
    c.addEventListener('pointerenter', () => (this.pointerOver = true));
    c.addEventListener('pointermove', () => (this.pointerOver = true));
    c.addEventListener('pointerleave', () => (this.pointerOver = false));
    // capture: before the shortcuts, which must not see the axis letters and digits
    window.addEventListener('keydown', (e) => this._key(e), true);
    window.addEventListener('pointerdown', (e) => this._pointer(e), true);
  }

  get active() {
    return this.entry !== null;
  }

  /**
   * Start a typed move ('translate') or rotation ('rotate') of the active group; false when none can start.
   * @param {'translate'|'rotate'} mode
   */
  start(mode) {
    if (this.entry) {
      this.entry.mode = mode;
      this._update(this.entry);
      return true;
    }
    if (!this.pointerOver || !this.canStart() || this.gizmo.dragging || !this.gizmo.indices.length) return false;
    this.entry = { mode, axis: null, text: '', group: this.gizmo.group, refused: null };
    this._update(this.entry);
    return true;
  }

  cancel() {
    if (!this.entry) return;
    this.entry = null;
    this.gizmo.cancelPreview();
    this.line.hidden = true;
  }

  /** Apply what was typed (nothing typed: nothing changes). */
  confirm() {
    const e = this.entry;
    if (!e) return;
    const m = e.text === '' ? null : this._matrix(e);
    this.entry = null;
    this.line.hidden = true;
    if (m) this.gizmo.apply(m);
    else this.gizmo.cancelPreview();
  }

  /** @param {Entry} e */
  _axis(e) {
    return e.axis ?? (e.mode === 'rotate' ? 'view' : 'x');
  }

  /** @param {Entry} e */
  _matrix(e) {
    return typedTransform(this.gizmo, this.viewer.camera, e.mode, this._axis(e), typedValue(e.text));
  }

  /** @param {Entry} e the entry under way */
  _update(e) {
    if (e.group !== this.gizmo.group || !this.gizmo.indices.length) {
      this.cancel();
      return;
    }
    const m = this._matrix(e);
    if (m) this.gizmo.preview(m);
    const axis = this._axis(e);
    const unit = e.mode === 'rotate' ? '°' : '';
    const refused = e.refused === null ? '' : `  (“${e.refused}” cannot go there)`;
    this.line.textContent = `${VERB[e.mode]} ${axis === 'view' ? 'view axis' : axis.toUpperCase()}: `
      + `${e.text === '' ? '…' : e.text}${unit}${refused}`;
    this.line.classList.toggle('refused', e.refused !== null);
    this.line.hidden = false;
  }

  /** @param {KeyboardEvent} ev */
  _key(ev) {
    const e = this.entry;
    if (!e || ev.isComposing) return;
    if (ev.ctrlKey || ev.metaKey || ev.altKey) {
      if (!['Control', 'Meta', 'Alt', 'Shift'].includes(ev.key)) this.cancel(); // undo and the like
      return;
    }
    const k = ev.key;
    if (k === 'Shift') return;
    ev.preventDefault();
    ev.stopPropagation();
    const lower = k.toLowerCase();
    e.refused = null;
    if (k === 'Escape') this.cancel();
    else if (k === 'Enter') this.confirm();
    else if (k === 'Backspace') e.text = e.text.slice(0, -1);
    else if (lower === 'x' || lower === 'y' || lower === 'z') e.axis = lower;
    else if (lower === 'g') e.mode = 'translate';
    else if (lower === 'r') e.mode = 'rotate';
    else if (k.length === 1) {
      const text = typedText(e.text, k); // a key that cannot be part of the number is shown refused
      if (text === null) e.refused = k;
      else e.text = text;
    }
    if (this.entry) this._update(this.entry);
  }

  /** @param {PointerEvent} ev */
  _pointer(ev) {
    if (!this.entry) return;
    // a click on the view applies (as in Blender), any other button or a click elsewhere cancels
    if (ev.target === this.viewer.canvas) {
      ev.stopImmediatePropagation();
      ev.preventDefault();
      if (ev.button === 0) this.confirm();
      else this.cancel();
      return;
    }
    this.cancel();
  }
}
