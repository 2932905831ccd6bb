// Keyboard shortcuts, kept out of the controls that take typed keys themselves, and the keyboard handed back to
// the shortcuts once a button, checkbox, slider or drop-down of the panel has been used with the pointer.

const TEXT_TYPES = new Set([
  'text', 'search', 'email', 'url', 'tel', 'password', 'number', 'date', 'datetime-local', 'month', 'time', 'week',
]);

/**
 * True for elements that read typed keys: text fields, text areas, drop-downs and editable content.
 * @param {EventTarget|null} el
 */
export function takesKeys(el) {
  if (!(el instanceof Element)) return false;
  if (el instanceof HTMLTextAreaElement || el instanceof HTMLSelectElement) return true;
  if (el instanceof HTMLInputElement) return TEXT_TYPES.has(el.type);
  return el instanceof HTMLElement && el.isContentEditable;
}

/**
 * Studio shortcuts on the whole document: Ctrl/Cmd+Z undo, Ctrl/Cmd+Shift+Z and Ctrl/Cmd+Y redo, and `keys`
 * (lower-case key → action) without modifiers. Events aimed at a control that takes keys are left alone.
 * `unbound(key)`, when given, hears of a printable key (no Ctrl, Cmd or Alt) that is no shortcut, so that the
 * page can say so instead of nothing happening.
 * @param {{undo: () => unknown, redo: () => unknown, keys: Record<string, () => unknown>,
 *   unbound?: (key: string) => unknown}} opts
 */
export function installShortcuts({ undo, redo, keys, unbound }) {
  document.addEventListener('keydown', (e) => {
    if (e.defaultPrevented || e.isComposing || takesKeys(e.target)) return;
    const k = e.key.toLowerCase();
    if ((e.ctrlKey || e.metaKey) && (k === 'z' || k === 'y')) {
      e.preventDefault();
      if (k === 'z' && !e.shiftKey) undo();
      else redo();
      return;
    }
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    if (Object.hasOwn(keys, k)) {
      keys[k]();
      e.preventDefault();
    } else if (unbound && e.key.length === 1 && e.key.trim() !== '' && !e.repeat) {
      unbound(e.key);
    }
  });
}

/**
 * Letters typed into a drop-down must not pick an option (a letter there is meant as a shortcut).
 * @param {HTMLElement} select a drop-down (a select element)
 */
export function ignoreTypeAhead(select) {
  select.addEventListener('keydown', (e) => {
    if (e.key.length === 1 && e.key !== ' ' && !e.ctrlKey && !e.metaKey && !e.altKey) e.preventDefault();
  });
}

const CONTROLS = 'button, select, input, [role="button"]';

/**
 * After a control inside `root` (other than a text field) has been used with the pointer, take the focus off it,
 * so that the shortcuts work again without clicking the 3D view first. Keyboard use keeps the focus.
 * @param {HTMLElement} root
 */
export function releaseFocusAfterPointerUse(root) {
  let byPointer = false;
  document.addEventListener('pointerdown', () => (byPointer = true), true);
  document.addEventListener('keydown', () => (byPointer = false), true);
  const release = (/** @type {Event} */ e) => {
    if (!byPointer) return;
    // a click on a drop-down opens it; only its change is the end of its use
    if (e.type === 'click' && e.target instanceof HTMLSelectElement) return;
    const used = document.activeElement; // the control the pointer just used
    setTimeout(() => {
      const el = document.activeElement;
      // only that control: the focus may have moved on meanwhile (e.g. to a drop-down the user now types in)
      if (!el || el !== used || !root.contains(el) || !el.matches(CONTROLS)) return;
      if (takesKeys(el) && !(el instanceof HTMLSelectElement)) return;
      /** @type {HTMLElement} */ (el).blur();
    }, 0);
  };
  root.addEventListener('click', release);
  root.addEventListener('change', release);
}
