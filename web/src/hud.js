// The statistics panel over the 3D view: moved by its title bar, collapsed on narrow views so it does not cover the
// model, and transparent to the pointer elsewhere (a box selection or a brush stroke may start over it).

/** Views narrower than this (CSS pixels) start with the statistics collapsed. */
export const NARROW_VIEW_PX = 760;

/**
 * @param {HTMLElement} hud the panel (class `collapsed` hides its body)
 * @param {HTMLElement} handle its title bar
 * @param {HTMLElement} toggle the collapse button inside the title bar
 */
export function installHud(hud, handle, toggle) {
  const setCollapsed = (/** @type {boolean} */ on) => {
    hud.classList.toggle('collapsed', on);
    toggle.textContent = on ? '+' : '–';
  };
  toggle.addEventListener('click', () => setCollapsed(!hud.classList.contains('collapsed')));

  /** @type {{id: number, dx: number, dy: number, parent: HTMLElement}|null} the title bar's drag under way */
  let drag = null;
  handle.addEventListener('pointerdown', (e) => {
    if (e.button !== 0 || (e.target instanceof Element && e.target.closest('button'))) return;
    const parent = /** @type {HTMLElement} */ (hud.offsetParent);
    drag = { id: e.pointerId, dx: e.clientX - hud.offsetLeft, dy: e.clientY - hud.offsetTop, parent };
    handle.setPointerCapture(e.pointerId);
    e.preventDefault();
  });
  handle.addEventListener('pointermove', (e) => {
    if (!drag || e.pointerId !== drag.id) return;
    const maxX = Math.max(0, drag.parent.clientWidth - hud.offsetWidth);
    const maxY = Math.max(0, drag.parent.clientHeight - hud.offsetHeight);
    hud.style.left = `${Math.max(0, Math.min(maxX, e.clientX - drag.dx))}px`;
    hud.style.top = `${Math.max(0, Math.min(maxY, e.clientY - drag.dy))}px`;
  });
  const end = (/** @type {PointerEvent} */ e) => {
    if (drag && e.pointerId === drag.id) drag = null;
  };
  handle.addEventListener('pointerup', end);
  handle.addEventListener('pointercancel', end);

  const view = /** @type {HTMLElement} */ (hud.parentElement);
  /** @type {boolean|null} the view was narrow at the last fit (null: not fitted yet) */
  let wasNarrow = null;
  const fit = () => {
    const narrow = view.clientWidth < NARROW_VIEW_PX;
    if (narrow !== wasNarrow) setCollapsed(narrow);
    wasNarrow = narrow;
  };
  new ResizeObserver(fit).observe(view);
  fit();
}
