// The studio as a Jupyter widget (anywidget's ES module): the studio page runs in a frame of the notebook's page
// (its own document, styles and keyboard shortcuts), and its session is carried by the kernel's comm: the frame's
// messages (connection.js, ModelConnection over parentModel) are forwarded to the widget model and back. No port
// and no server: it works wherever the notebook's widgets do (JupyterLab, Notebook 7, VS Code, Colab, remote kernels).
// Every view of one widget shares its session: a view names itself in what it sends ("view"), and drops the kernel's
// messages addressed to another view ("to": its greeting, an export, an error), so only the view that asked gets them.
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
  /** @param {any} content @param {(ArrayBuffer|ArrayBufferView)[]} [buffers] */
  const toFrame = (content, buffers) => {
    if (!content || typeof content !== 'object') return;
    const { to, ...message } = content;
    if (to !== undefined && to !== view) return; // another view's answer
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
    frame.remove();
  };
}

/** A name for one view, unique among the views of a page (the kernel echoes it in the replies for this view). */
function viewName() {
  const bytes = new Uint8Array(8);
  crypto.getRandomValues(bytes);
  return Array.from(bytes, (b) => b.toString(16).padStart(2, '0')).join('');
}

export default { render };
