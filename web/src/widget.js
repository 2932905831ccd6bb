// The studio as a Jupyter widget (anywidget's ES module): the studio page runs in a frame of the notebook's page
// (its own document, styles and keyboard shortcuts), and its session is carried by the kernel's comm: the frame's
// messages (connection.js, ModelConnection over parentModel) are forwarded to the widget model and back. No port
// and no server: it works wherever the notebook's widgets do (JupyterLab, Notebook 7, VS Code, Colab, remote kernels).
// Every view of one widget shares its session: a view names itself in what it sends ("view"), and drops the kernel's
// messages addressed to another view ("to": its greeting, an export, an error), so only the view that asked gets them.
// The kernel's own messages ({widget: ...}) are for this module, not the page: {widget: "preparing"} (with a picture
// of the mesh) says the greeting waits for the session, whose solver compiles on a first run, so the view shows the
// mesh and the time waited until the page is greeted; {widget: "stopped"} says the widget was stopped in the kernel
// (its .stop()), so the view says so over the page, which no longer gets answers.
// @ts-ignore: a module of the build (vite.config.js): the built studio page with its script and styles inlined
import page from 'virtual:arap-studio-page';

/**
 * @typedef {import('./connection.js').WidgetModel & {get: (name: string) => any}} Model
 */

/**
 * Show the studio in `el` (anywidget's render).
 * @param {{model: Model, el: HTMLElement}} ctx
 * @returns {() => void} removes the view
 */
export function render({ model, el }) {
  const frame = document.createElement('iframe');
  frame.title = 'ARAP Studio';
  frame.dataset.testid = 'arap-widget-frame';
  const height = Number(model.get('height')) || 640;
  frame.style.cssText = `display: block; width: 100%; height: ${height}px; border: 0;`;
  const view = viewName();
  /** @type {(() => void) | null} removes the note shown while the session is prepared */
  let preparing = null;
  /** @param {any} content @param {(ArrayBuffer|ArrayBufferView)[]} [buffers] */
  const toFrame = (content, buffers) => {
    if (!content || typeof content !== 'object') return;
    const { to, ...message } = content;
    if (to !== undefined && to !== view) return; // another view's answer
    if ('widget' in message) {
      if (message.widget === 'preparing' && !preparing) preparing = showPreparing(el, message, buffers?.[0]);
      if (message.widget === 'stopped') {
        preparing?.();
        preparing = null;
        showStopped(el, frame);
      }
      return;
    }
    preparing?.(); // the page's greeting: it shows the mesh itself now
    preparing = null;
    frame.contentWindow?.postMessage({ arap: 'msg', content: message, buffers: buffers ?? [] }, '*');
  };
  /** @param {MessageEvent} ev */
  const fromFrame = (ev) => {
    if (ev.source !== frame.contentWindow || !ev.data || ev.data.arap !== 'send') return;
    model.send({ ...ev.data.content, view }, undefined, ev.data.buffers);
  };
  window.addEventListener('message', fromFrame);
  model.on('msg:custom', toFrame);
  frame.srcdoc = page;
  el.appendChild(frame);
  return () => {
    model.off('msg:custom', toFrame);
    window.removeEventListener('message', fromFrame);
    preparing?.();
    frame.remove();
    el.querySelector('[data-testid=arap-widget-stopped]')?.remove();
  };
}

/** How long a view waits for its greeting before it shows the kernel's picture of the mesh and the time waited. */
const PREPARING_NOTE_DELAY_MS = 400;

/**
 * Show, over the page, the mesh (the kernel's picture) and how long the session has been prepared, until the page is
 * greeted.
 * @param {HTMLElement} el
 * @param {{first_run?: boolean}} message
 * @param {ArrayBuffer|ArrayBufferView} [png] the picture
 * @returns {() => void} removes it
 */
function showPreparing(el, message, png) {
  el.style.position = 'relative';
  const note = document.createElement('div');
  note.dataset.testid = 'arap-widget-preparing';
  note.setAttribute('role', 'status');
  note.style.cssText = 'position: absolute; inset: 0; display: flex; flex-direction: column; align-items: center;'
    + ' justify-content: center; gap: 0.8em; padding: 1em; background: #20242b; color: #e8e8e8;'
    + ' font: 14px/1.5 system-ui, sans-serif; text-align: center;';
  /** @type {string | null} */
  let url = null;
  if (png) {
    const view = png instanceof ArrayBuffer ? new Uint8Array(png)
      : new Uint8Array(png.buffer, png.byteOffset, png.byteLength);
    const bytes = new Uint8Array(view.byteLength); // a copy the Blob can take (the comm's buffer may be shared)
    bytes.set(view);
    url = URL.createObjectURL(new Blob([bytes], { type: 'image/png' }));
    const picture = document.createElement('img');
    picture.src = url;
    picture.alt = 'The mesh, at rest';
    picture.style.cssText = 'max-width: 100%; max-height: 60%; border-radius: 4px;';
    note.appendChild(picture);
  }
  const text = document.createElement('div');
  const why = message.first_run
    ? 'The first run in this environment compiles the solver (from ten seconds to a few minutes, once).'
    : 'The kernel is loading the mesh.';
  const started = Date.now();
  const tick = () => {
    text.textContent = `Preparing the solver… ${Math.round((Date.now() - started) / 1000)} s. ${why}`;
  };
  tick();
  const timer = setInterval(tick, 1000);
  note.appendChild(text);
  note.style.visibility = 'hidden'; // shown only if the wait is noticeable: no flash when the kernels are cached
  const shown = setTimeout(() => { note.style.visibility = 'visible'; }, PREPARING_NOTE_DELAY_MS);
  el.appendChild(note);
  return () => {
    clearTimeout(shown);
    clearInterval(timer);
    note.remove();
    if (url) URL.revokeObjectURL(url);
  };
}

/**
 * Say over the page that the widget was stopped in the kernel, and how to get a studio again; the page stays under
 * it, dimmed, with the last shape it showed.
 * @param {HTMLElement} el
 * @param {HTMLIFrameElement} frame
 */
function showStopped(el, frame) {
  if (el.querySelector('[data-testid=arap-widget-stopped]')) return;
  el.style.position = 'relative';
  frame.style.opacity = '0.35';
  frame.style.pointerEvents = 'none';
  const note = document.createElement('div');
  note.dataset.testid = 'arap-widget-stopped';
  note.setAttribute('role', 'status');
  note.style.cssText = 'position: absolute; inset: 0; display: flex; align-items: center; justify-content: center;'
    + ' padding: 1em; font: 14px/1.5 system-ui, sans-serif; text-align: center;';
  const box = document.createElement('div');
  box.style.cssText = 'max-width: 32em; padding: 1em 1.4em; border-radius: 6px; background: #20242b; color: #e8e8e8;'
    + ' box-shadow: 0 2px 12px rgba(0, 0, 0, 0.4);';
  const title = document.createElement('strong');
  title.textContent = 'This studio was stopped in the kernel.';
  const text = document.createElement('div');
  text.textContent = 'It no longer answers this page (its stop() was called in Python). Its results'
    + ' stay readable in Python (.vertices, .constraints); run the cell that made it again to start a new studio.';
  box.append(title, text);
  note.appendChild(box);
  el.appendChild(note);
}

/** A name for one view, unique among the views of a page (the kernel echoes it in the replies for this view). */
function viewName() {
  const bytes = new Uint8Array(8);
  crypto.getRandomValues(bytes);
  return Array.from(bytes, (b) => b.toString(16).padStart(2, '0')).join('');
}

export default { render };
