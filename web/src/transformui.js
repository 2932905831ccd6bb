// The Manipulate section's pivot, axes, snapping and exact-transform controls, and their shortcuts (G, R, P, C, L).
import { byId } from './dom.js';
import { SHORTCUTS } from './help.js';
import { ignoreTypeAhead } from './keys.js';
import { NumericEntry, typedTransform } from './numeric.js';
import { PivotPicker } from './pivot.js';
import { ROTATION_SNAP_DEG } from './transform.js';

SHORTCUTS.push(
  { key: 'g', label: 'G', does: 'Move the active handle group by a typed amount (then X/Y/Z, digits, Enter)' },
  { key: 'r', label: 'R', does: 'Rotate the active handle group by typed degrees (then X/Y/Z, digits, Enter)' },
  { key: 'p', label: 'P', does: 'Place the pivot: click on the surface' },
  { key: 'c', label: 'C', does: 'Pivot back to the group\'s centroid' },
  { key: 'l', label: 'L', does: 'Gizmo axes: local (the group\'s rotation) or world' },
  { key: null, label: 'Ctrl+drag gizmo', does: 'Snap: rotations to 15°, moves to the grid' },
);


/**
 * Wire the controls to the gizmo. Call it before the selection tools and the orbit controls are created (the
 * pivot's click on the surface goes first).
 * @param {object} opts
 * @param {import('./viewer.js').Viewer} opts.viewer
 * @param {import('./gizmo.js').HandleGizmo} opts.gizmo
 * @param {() => boolean} opts.canStart a typed transform may start: studio ready
 * @param {(text: string) => void} opts.say show a short message
 * @param {() => void} opts.hush take it away
 * @returns {{keys: Record<string, () => void>, meshChanged: () => void, entry: NumericEntry,
 *   picker: PivotPicker}}
 */
export function installTransformUi({ viewer, gizmo, canStart, say, hush }) {
  const placeBtn = byId('btn-place-pivot');
  const changed = (/** @type {boolean} */ on) => placeBtn.classList.toggle('active', on);
  const picker = new PivotPicker({ viewer, gizmo, say, hush, changed });
  const entry = new NumericEntry({ gizmo, viewer, line: byId('numeric-line'), canStart });
  const local = /** @type {HTMLInputElement} */ (byId('local-axes'));
  const snap = /** @type {HTMLInputElement} */ (byId('snap'));
  const mode = /** @type {HTMLSelectElement} */ (byId('exact-mode'));
  const axis = /** @type {HTMLSelectElement} */ (byId('exact-axis'));
  const amount = /** @type {HTMLInputElement} */ (byId('exact-amount'));

  const setSpace = (/** @type {boolean} */ isLocal) => {
    local.checked = isLocal;
    gizmo.setSpace(isLocal ? 'local' : 'world');
  };
  placeBtn.addEventListener('click', () => picker.toggle());
  byId('btn-reset-pivot').addEventListener('click', () => picker.reset());
  local.addEventListener('change', () => setSpace(local.checked));
  snap.addEventListener('change', () => gizmo.setSnap(snap.checked));
  ignoreTypeAhead(mode);
  ignoreTypeAhead(axis);
  mode.addEventListener('change', () => (amount.title = mode.value === 'rotate' ? 'Degrees' : 'Model units'));

  const applyFields = () => {
    const value = Number.parseFloat(amount.value);
    if (!Number.isFinite(value)) {
      say('Type the amount: a distance in model units, or an angle in degrees.');
      return;
    }
    if (!canStart() || !gizmo.indices.length) {
      say('Pick a handle group first.');
      return;
    }
    const m = typedTransform(gizmo, viewer.camera, mode.value, axis.value, value);
    if (m) gizmo.apply(m);
  };
  byId('btn-exact-apply').addEventListener('click', applyFields);
  amount.addEventListener('keydown', (e) => {
    if (e.key === 'Enter') applyFields();
  });

  // while the pointer drags the gizmo, the same line shows the angle or distance so far
  const line = byId('numeric-line');
  gizmo.controls.addEventListener('objectChange', () => {
    if (entry.active || !gizmo.dragging) return;
    line.textContent = gizmo.controls.dragText();
    line.classList.add('dragging');
    line.hidden = false;
  });
  gizmo.controls.addEventListener('mouseUp', () => {
    if (!line.classList.contains('dragging')) return;
    line.classList.remove('dragging');
    if (!entry.active) line.hidden = true;
  });

  const meshChanged = () => {
    picker.stop();
    gizmo.meshChanged();
    entry.cancel();
    byId('snap-step').textContent = `grid ${gizmo.gridStep}, ${ROTATION_SNAP_DEG}°`;
  };

  const startEntry = (/** @type {'translate'|'rotate'} */ what) => {
    if (entry.start(what)) return;
    const key = what === 'rotate' ? 'R' : 'G';
    if (!gizmo.indices.length) say('Pick a handle group first: G and R move or turn it.');
    else if (!entry.pointerOver && canStart() && !gizmo.dragging) {
      say(`Point at the 3D view, then press ${key}: the typed ${what === 'rotate' ? 'rotation' : 'move'} starts `
        + 'there.');
    }
  };

  return {
    keys: {
      g: () => startEntry('translate'),
      r: () => startEntry('rotate'),
      p: () => picker.toggle(),
      c: () => picker.reset(),
      l: () => setSpace(gizmo.space !== 'local'),
    },
    meshChanged,
    entry,
    picker,
  };
}
