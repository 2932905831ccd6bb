// "Place pivot": after the action, a click on the surface puts the active handle group's pivot at the point hit.
import * as THREE from 'three';

export class PivotPicker {
  /**
   * Create it before the selection tools and the orbit controls: its pointer handler on the canvas must run
   * first, to keep the placing click from painting or orbiting.
   * @param {object} opts
   * @param {import('./viewer.js').Viewer} opts.viewer
   * @param {import('./gizmo.js').HandleGizmo} opts.gizmo
   * @param {(placing: boolean) => void} opts.changed the placing mode began or ended
   * @param {(text: string) => void} opts.say show a short message
   * @param {() => void} opts.hush take the message away
   */
  constructor({ viewer, gizmo, changed, say, hush }) {
    this.viewer = viewer;
    this.gizmo = gizmo;
    this.changed = changed;
    this.say = say;
    this.hush = hush;
    this.placing = false;
    this.raycaster = new THREE.Raycaster();
    viewer.canvas.addEventListener('pointerdown', (e) => this._down(e));
    window.addEventListener('keydown', (e) => {
      if (this.placing && e.key === 'Escape') {
        e.preventDefault();
        e.stopPropagation();
        this.stop();
      }
    }, true);
  }

  /** Wait for a click on the surface (again: stop waiting). */
  toggle() {
    if (this.placing) {
      this.stop();
      return;
    }
    if (!this.gizmo.indices.length) {
      this.say('Pick a handle group first: the pivot belongs to the active group.');
      return;
    }
    this.placing = true;
    this.gizmo.controls.enabled = false;
    this.viewer.canvas.style.cursor = 'crosshair';
    this.say('Click on the surface to put the pivot there (Esc: cancel).');
    this.changed(true);
  }

  stop() {
    if (!this.placing) return;
    this.placing = false;
    this.hush();
    this.gizmo.controls.enabled = true;
    this.viewer.canvas.style.cursor = '';
    this.changed(false);
  }

  /** The pivot back to the group's centroid. */
  reset() {
    this.stop();
    this.gizmo.resetPivot();
  }

  /** @param {PointerEvent} e a press on the canvas */
  _down(e) {
    if (!this.placing) return;
    e.stopImmediatePropagation();
    e.preventDefault();
    if (e.button !== 0) {
      this.stop();
      return;
    }
    const v = this.viewer;
    const r = v.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    this.raycaster.setFromCamera(ndc, v.camera);
    const hit = v.mesh ? this.raycaster.intersectObject(v.mesh, false)[0] : undefined;
    if (!hit) {
      this.say('No surface under the pointer: click on the model.');
      return;
    }
    this.gizmo.placePivot(hit.point.toArray());
    this.stop();
  }
}
