// Help: the table of every shortcut (the one place they are described), the "?" overlay built from it, and the
// first-run guide (anchor → handle → drag), dismissed once and remembered.
import { byId, inside } from './dom.js';

/**
 * Every shortcut of the studio. `key` is the lower-case `KeyboardEvent.key` a plain key press triggers (see
 * keys.js installShortcuts), or null for pointer gestures and modifier combinations handled elsewhere; `label` is
 * what the overlay shows. Extend it with `SHORTCUTS.push(...)` before the studio starts.
 * @type {{key: string|null, label: string, does: string}[]}
 */
export const SHORTCUTS = [
  { key: '1', label: '1', does: 'Paint the region of interest' },
  { key: '2', label: '2', does: 'Paint fixed anchors' },
  { key: '3', label: '3', does: 'Paint the active handle group' },
  { key: '4', label: '4', does: 'Erase any role' },
  { key: '5', label: '5', does: 'Point handle mode: a click on the surface places a handle there' },
  { key: '6', label: '6', does: 'Stiffness brush: painted parts bend less (rigid: not at all)' },
  { key: 'b', label: 'B', does: 'Brush tool' },
  { key: 'x', label: 'X', does: 'Box select tool' },
  { key: 'o', label: 'O', does: 'Orbit only' },
  { key: 'n', label: 'N', does: 'New handle group' },
  { key: 'w', label: 'W', does: 'Move handles (translate)' },
  { key: 'e', label: 'E', does: 'Rotate handles' },
  { key: 'f', label: 'F', does: 'Fit the mesh into view' },
  { key: '+', label: '+', does: 'Grow the current role by one ring' },
  { key: '=', label: '=', does: 'Grow the current role by one ring (without Shift)' },
  { key: '-', label: '−', does: 'Shrink the current role by one ring' },
  { key: 'h', label: 'H', does: 'Show or hide the distortion heat map' },
  { key: 'm', label: 'M', does: 'Mirror editing on or off (selections and drags act on both sides)' },
  { key: 'k', label: 'K', does: 'Add a keyframe: the handle groups\' current transforms at the timeline\'s playhead' },
  { key: 'delete', label: 'Delete', does: 'Remove the active point handle (a picture\'s pin)' },
  { key: '?', label: '?', does: 'Show or hide this help' },
  { key: 'escape', label: 'Esc', does: 'Close the help or the message' },
  { key: null, label: 'Ctrl+Z', does: 'Undo' },
  { key: null, label: 'Ctrl+Shift+Z / Ctrl+Y', does: 'Redo' },
  { key: null, label: 'Left drag', does: 'Paint with the brush, or orbit over empty space' },
  { key: null, label: 'Shift+drag', does: 'Box select' },
  { key: null, label: 'Ctrl+paint', does: 'Remove the current role (stiffness: back to 1)' },
  { key: null, label: 'Ctrl+click', does: 'Remove the point handle under the pointer (point handle mode)' },
  { key: null, label: 'Alt+drag', does: 'Turn a picture about its active pin (start near the pin): the pin keeps that angle' },
  { key: null, label: 'Right drag', does: 'Pan' },
  { key: null, label: 'Wheel', does: 'Zoom' },
  {
    key: null,
    label: 'Timeline',
    does: 'Animation: drag along the time bar to scrub (the shape follows), click a keyframe\'s marker to go to it; '
      + 'Play loops at the frame rate, Export animation solves every frame and downloads an animated GLB',
  },
  {
    key: null,
    label: 'Surface',
    does: 'Display → Surface (textured or coloured models): draw the model with its texture, its vertex colours or '
      + 'plain. Painting keeps the view: anchors, handles and stiffness are mixed over the texture or colours at 70% '
      + '(outside the region of interest greyed at 55%); choose Plain for the full role colours',
  },
];

/**
 * The `keys` map for installShortcuts from handlers by key; a handler for a key the table does not describe is
 * an error, so the overlay always lists every shortcut.
 * @param {Record<string, () => void>} handlers
 * @returns {Record<string, () => void>}
 */
export function describedKeys(handlers) {
  const known = new Set(SHORTCUTS.map((s) => s.key).filter((k) => k !== null));
  for (const key of Object.keys(handlers)) {
    if (!known.has(key)) throw new Error(`shortcut ${key} is missing from the help table (help.js SHORTCUTS)`);
  }
  return handlers;
}

const GUIDE_KEY = 'arap.guide.dismissed';
/** How long the guide stays once its last step is done. */
const GUIDE_CLOSE_MS = 1500;

export class Help {
  /**
   * @param {HTMLElement} overlay the "?" overlay
   * @param {HTMLElement} guide the first-run guide
   * @param {HTMLElement} button opens and closes the overlay
   */
  constructor(overlay = byId('help'), guide = byId('guide'), button = byId('btn-help')) {
    button.addEventListener('click', () => this.toggle());
    this.overlay = overlay;
    this.guide = guide;
    const table = inside(overlay, 'tbody');
    for (const s of SHORTCUTS) {
      const tr = document.createElement('tr');
      const th = document.createElement('th');
      const kbd = document.createElement('kbd');
      kbd.textContent = s.label;
      th.appendChild(kbd);
      const td = document.createElement('td');
      td.textContent = s.does;
      tr.append(th, td);
      table.appendChild(tr);
    }
    overlay.addEventListener('click', (e) => {
      if (e.target === overlay || (e.target instanceof Element && e.target.closest('.help-close'))) this.hide();
    });
    inside(guide, '.guide-close').addEventListener('click', () => this.dismissGuide());
    guide.hidden = remembered();
    /** The guide's steps done so far (its list items, in order: anchors, handle, drag). */
    this.done = { anchors: false, handle: false, drag: false };
    this._closing = 0;
  }

  /**
   * Some of the guide's steps were done (`{anchors, handle, drag}`, true for those done now): each is ticked off,
   * and once all three are the guide closes by itself (after a moment, so that the last tick is seen) for good.
   * @param {{anchors?: boolean, handle?: boolean, drag?: boolean}} steps
   */
  guideProgress(steps) {
    if (this.guide.hidden || this._closing) return;
    const items = this.guide.querySelectorAll('li');
    /** @type {('anchors'|'handle'|'drag')[]} */ (['anchors', 'handle', 'drag']).forEach((step, k) => {
      if (!steps[step] || this.done[step]) return;
      this.done[step] = true;
      items[k]?.classList.add('done');
    });
    if (this.done.anchors && this.done.handle && this.done.drag) {
      this._closing = window.setTimeout(() => this.dismissGuide(), GUIDE_CLOSE_MS);
    }
  }

  get shown() {
    return !this.overlay.hidden;
  }

  toggle() {
    this.overlay.hidden = !this.overlay.hidden;
  }

  hide() {
    this.overlay.hidden = true;
  }

  /** Close the first-run guide for good (remembered in localStorage where the browser allows it). */
  dismissGuide() {
    this.guide.hidden = true;
    try {
      localStorage.setItem(GUIDE_KEY, '1');
    } catch (err) {
      if (!(err instanceof DOMException)) throw err; // storage disabled: the guide comes back next time
    }
  }
}

function remembered() {
  try {
    return localStorage.getItem(GUIDE_KEY) === '1';
  } catch (err) {
    if (err instanceof DOMException) return false;
    throw err;
  }
}
