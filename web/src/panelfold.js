// Folding the side panel away (to a narrow strip with the button that brings it back), so that a small window
// gives the 3D view its width; the view follows the panel's width by itself (Viewer's ResizeObserver).

/**
 * @param {HTMLElement} panel the side panel (class `collapsed` folds it)
 * @param {HTMLButtonElement} toggle the button in its head that folds and unfolds it
 */
export function installPanelFold(panel, toggle) {
  const set = (/** @type {boolean} */ folded) => {
    panel.classList.toggle('collapsed', folded);
    toggle.textContent = folded ? '«' : '»';
    toggle.title = folded ? 'Show the panel' : 'Hide the panel (more room for the view)';
    toggle.setAttribute('aria-expanded', String(!folded));
  };
  toggle.addEventListener('click', () => set(!panel.classList.contains('collapsed')));
  set(false);
}
