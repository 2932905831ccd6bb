// WebSocket session with the studio server: framing, reconnection and drag coalescing.
import { decodeBinary, encodeBinary } from './frames.js';
import { CLIENT, ERROR, SERVER } from './protocol.js';

const DRAG_REPLY_TIMEOUT_MS = 5000;
const RETRY_FIRST_MS = 500; // delay before the first reconnection attempt; doubled after each failure
const RETRY_MAX_MS = 8000;
/** Delay between attempts while the server is full (it refused the tab): another tab must close first. */
export const FULL_RETRY_MS = 15000;
/** Close code of a server that refuses a session because it serves as many as it allows ("try again later"). */
const FULL_CLOSE_CODE = 1013;
/**
 * A connection open this long without the server's welcome is waiting for the solver: on a fresh install the
 * server compiles its kernels first (tens of seconds), and the page says so rather than nothing.
 */
export const WELCOME_WAIT_MS = 1500;

/**
 * A server message as handed on: a binary one as its header fields plus its `frame` (see decodeBinary).
 * @typedef {import('./protocol.js').ServerMessage & {frame?: {header: any, payload: Uint8Array}}} ReceivedMessage
 */

/**
 * What a connection tells.
 * @typedef {object} ConnectionHandlers
 * @property {() => void} [onOpen] the server greeted a new connection: called before its welcome is handed on
 * @property {(event: CloseEvent) => void} [onClose] an open connection was lost or closed
 * @property {(refusal: {reason: string, delayMs: number}) => void} [onRefused] the server is full: it refused the
 *   connection, tried again after delayMs; onClose and onRetry are not called
 * @property {(retry: {attempt: number, delayMs: number}) => void} [onRetry] a reconnection is scheduled
 * @property {() => void} [onWaiting] the connection is open but the server has not greeted it after
 *   WELCOME_WAIT_MS: it is preparing the solver
 * @property {(msg: ReceivedMessage) => void} [onMessage] a message of the server
 */

/**
 * A binary message's payload as a widget model carries it.
 * @typedef {ArrayBuffer|ArrayBufferView} Buffer
 */

/**
 * A listener of a widget model's custom messages: `content` is whatever JSON the kernel sent.
 * @typedef {(content: any, buffers?: Buffer[]) => void} CustomListener
 */

export class Connection {
  /**
   * @param {string} url WebSocket address
   * @param {ConnectionHandlers} [handlers] what it tells (also given later: listen)
   */
  constructor(url, handlers = {}) {
    this.url = url;
    this.handlers = handlers;
    this.ws = null;
    this.open = false;
    this.seq = 0;
    this.inFlight = null; // {seq, sentAt}
    this.pending = null; // latest unsent transforms
    /** @type {number|undefined} the keyframe whose pose the pending transforms are */
    this.pendingKey = undefined;
    this.endDragQueued = false;
    this.lastLatencyMs = null;
    this.attempt = 0; // failed connection attempts in a row
    this.retryTimer = null;
    this.stopped = false;
    this.welcomed = false; // the current connection was greeted
    this.refusal = null; // why the server refused the current connection (its busy error, before any welcome)
    /** @type {ReturnType<typeof setTimeout> | undefined} */
    this.welcomeTimer = undefined; // fires onWaiting when the welcome is late
  }

  /**
   * Tell `handlers` from now on what happens to the connection (instead of the handlers it had).
   * @param {ConnectionHandlers} handlers
   */
  listen(handlers) {
    this.handlers = handlers;
  }

  /** Connect now (also cancels a scheduled reconnection); a lost connection is retried with backoff. */
  connect() {
    this.stopped = false;
    clearTimeout(this.retryTimer ?? undefined);
    this.retryTimer = null;
    if (this.ws && (this.ws.readyState === WebSocket.OPEN || this.ws.readyState === WebSocket.CONNECTING)) return;
    const ws = new WebSocket(this.url);
    ws.binaryType = 'arraybuffer';
    this.ws = ws;
    this.welcomed = false;
    this.refusal = null;
    let opened = false;
    ws.addEventListener('open', () => {
      opened = true;
      this.open = true;
      this.inFlight = null;
      this.pending = null;
      clearTimeout(this.welcomeTimer);
      this.welcomeTimer = setTimeout(() => {
        if (this.ws === ws && this.open && !this.welcomed) this.handlers.onWaiting?.();
      }, WELCOME_WAIT_MS);
    });
    ws.addEventListener('close', (ev) => {
      if (this.ws !== ws) return;
      clearTimeout(this.welcomeTimer);
      this.open = false;
      this.inFlight = null;
      this.pending = null;
      if (opened && !this.welcomed && (this.refusal !== null || ev.code === FULL_CLOSE_CODE)) {
        this._refused(this.refusal || ev.reason);
        return;
      }
      if (opened) this.handlers.onClose?.(ev);
      this._scheduleRetry();
    });
    ws.addEventListener('message', (ev) => this._receive(ev.data));
  }

  /** Close for good (no reconnection). */
  close() {
    this.stopped = true;
    clearTimeout(this.retryTimer ?? undefined);
    this.retryTimer = null;
    this.ws?.close();
  }

  /**
   * The server is full: tell, and try again slowly (a tab must close first).
   * @param {string} reason
   */
  _refused(reason) {
    if (this.stopped) return;
    this.retryTimer = setTimeout(() => this.connect(), FULL_RETRY_MS);
    this.handlers.onRefused?.({ reason: reason || '', delayMs: FULL_RETRY_MS });
  }

  _scheduleRetry() {
    if (this.stopped) return;
    const delayMs = Math.min(RETRY_MAX_MS, RETRY_FIRST_MS * 2 ** this.attempt);
    this.attempt += 1;
    this.retryTimer = setTimeout(() => this.connect(), delayMs);
    this.handlers.onRetry?.({ attempt: this.attempt, delayMs });
  }

  get retrying() {
    return this.retryTimer !== null;
  }

  /**
   * Send a text message; false when the connection is not open.
   * @param {import('./protocol.js').ClientMessage} msg
   * @returns {boolean}
   */
  send(msg) {
    if (!this.open) return false;
    /** @type {WebSocket} */ (this.ws).send(JSON.stringify(msg)); // open: there is one
    return true;
  }

  /**
   * Send a binary message (header and payload); false when the connection is not open.
   * @param {import('./protocol.js').UploadClientMessage} header
   * @param {ArrayBuffer|ArrayBufferView} bytes
   * @returns {boolean}
   */
  sendBinary(header, bytes) {
    if (!this.open) return false;
    /** @type {WebSocket} */ (this.ws).send(encodeBinary(header, bytes));
    return true;
  }

  /**
   * Queue a drag; at most one drag is unanswered, later ones collapse into the newest.
   * @param {number[][]} transforms one 4x4 matrix per handle group, then per point handle (see DragClientMessage)
   * @param {number} [key] the keyframe whose pose these are (DragClientMessage.key)
   */
  drag(transforms, key) {
    if (this.inFlight && performance.now() - this.inFlight.sentAt > DRAG_REPLY_TIMEOUT_MS) this.inFlight = null;
    if (this.inFlight) {
      this.pending = transforms;
      this.pendingKey = key;
      return;
    }
    this._sendDrag(transforms, key);
  }

  /** Finish a drag: the newest transforms go out first, then end_drag. */
  endDrag() {
    if (this.pending) {
      this._sendDrag(this.pending, this.pendingKey);
      this.pending = null;
    }
    this.send({ type: CLIENT.END_DRAG });
  }

  get dragBusy() {
    return this.inFlight !== null;
  }

  /** @param {number[][]} transforms @param {number} [key] */
  _sendDrag(transforms, key) {
    this.seq += 1;
    if (this.send({ type: CLIENT.DRAG, seq: this.seq, transforms, ...(key === undefined ? {} : { key }) })) {
      this.inFlight = { seq: this.seq, sentAt: performance.now() };
    }
  }

  /** @param {number} seq the drag answered */
  _dragAnswered(seq) {
    if (!this.inFlight || seq < this.inFlight.seq) return;
    this.lastLatencyMs = performance.now() - this.inFlight.sentAt;
    this.inFlight = null;
    if (this.pending) {
      const t = this.pending;
      this.pending = null;
      this._sendDrag(t, this.pendingKey);
    }
  }

  /** @param {string|ArrayBuffer} data a text or binary WebSocket message */
  _receive(data) {
    /** @type {ReceivedMessage} */
    let msg;
    try {
      if (typeof data === 'string') {
        msg = JSON.parse(data);
      } else {
        const frame = decodeBinary(data);
        msg = { ...frame.header, frame };
      }
    } catch (err) {
      this.handlers.onMessage?.({ type: 'error', code: 'bad_message', message: `unreadable frame: ${err}`, request: null });
      return;
    }
    this._dispatch(msg);
  }

  /**
   * Hand on a decoded server message (a binary one with its `frame`).
   * @param {ReceivedMessage} msg
   */
  _dispatch(msg) {
    if (msg.type === SERVER.WELCOME) {
      this.attempt = 0; // a server that accepts and drops at once still backs off
      this.welcomed = true;
      clearTimeout(this.welcomeTimer);
      this.handlers.onOpen?.();
    } else if (msg.type === SERVER.ERROR && msg.code === ERROR.BUSY && !this.welcomed) {
      this.refusal = msg.message || 'the studio server is full'; // it closes the connection next
    }
    if (msg.type === SERVER.VERTICES && typeof msg.seq === 'number' && msg.seq >= 0) this._dragAnswered(msg.seq);
    if (msg.type === SERVER.ERROR && msg.request === CLIENT.DRAG && this.inFlight) this._dragAnswered(this.inFlight.seq);
    this.handlers.onMessage?.(msg);
  }
}

/**
 * WebSocket address of the studio that served this page: `ws(s)://host/path/ws`, with the page's `?token=` when it
 * has one (a studio serving a network, or a notebook's, refuses connections without its token).
 * @param {{protocol: string, host: string, pathname: string, search: string}} [loc] the page's location
 * @returns {string}
 */
export function defaultSocketUrl(loc = location) {
  const proto = loc.protocol === 'https:' ? 'wss:' : 'ws:';
  const base = loc.pathname.replace(/[^/]*$/, '');
  const token = new URLSearchParams(loc.search).get('token');
  const query = token === null ? '' : `?token=${encodeURIComponent(token)}`;
  return `${proto}//${loc.host}${base}ws${query}`;
}

/**
 * What a studio session needs of a Jupyter widget model (anywidget's `model`): custom messages both ways, a binary
 * message as its header (the content) and its payload (the first buffer).
 * @typedef {{
 *   send: (content: object, callbacks?: unknown, buffers?: Buffer[]) => void,
 *   on: (name: 'msg:custom', cb: (content: any, buffers?: Buffer[]) => void) => void,
 *   off: (name: 'msg:custom', cb: (content: any, buffers?: Buffer[]) => void) => void,
 * }} WidgetModel
 */

/** The message a widget view sends when it opens: the kernel answers with the greeting (welcome, mesh, state). */
export const WIDGET_OPEN = { widget: 'open' };

/**
 * The studio session of a notebook widget: the same interface as Connection, carried by the kernel's comm (the
 * widget model's custom messages) instead of a WebSocket. There is no reconnection: the comm lives as long as the
 * kernel keeps the widget.
 */
export class ModelConnection extends Connection {
  /**
   * @param {WidgetModel} model
   * @param {ConnectionHandlers} [handlers] what it tells (also given later: listen)
   */
  constructor(model, handlers = {}) {
    super('', handlers);
    this.model = model;
    /** @type {CustomListener} */
    this._listener = (content, buffers) => this._custom(content, buffers);
  }

  connect() {
    if (this.open) return;
    this.stopped = false;
    this.open = true;
    this.welcomed = false;
    this.inFlight = null;
    this.pending = null;
    this.model.on('msg:custom', this._listener);
    clearTimeout(this.welcomeTimer);
    this.welcomeTimer = setTimeout(() => {
      if (this.open && !this.welcomed) this.handlers.onWaiting?.();
    }, WELCOME_WAIT_MS);
    this.model.send(WIDGET_OPEN);
  }

  close() {
    this.stopped = true;
    clearTimeout(this.welcomeTimer);
    if (!this.open) return;
    this.open = false;
    this.model.off('msg:custom', this._listener);
  }

  get retrying() {
    return false;
  }

  /**
   * @param {import('./protocol.js').ClientMessage} msg
   * @returns {boolean}
   */
  send(msg) {
    if (!this.open) return false;
    this.model.send(msg);
    return true;
  }

  /**
   * @param {import('./protocol.js').UploadClientMessage} header
   * @param {Buffer} bytes
   * @returns {boolean}
   */
  sendBinary(header, bytes) {
    if (!this.open) return false;
    this.model.send(header, undefined, [bytes]);
    return true;
  }

  /** @type {CustomListener} */
  _custom(content, buffers) {
    if (!content || typeof content !== 'object' || typeof content.type !== 'string') return;
    if (!buffers || buffers.length === 0) {
      this._dispatch(content);
      return;
    }
    const b = buffers[0];
    const payload = b instanceof ArrayBuffer ? new Uint8Array(b) : new Uint8Array(b.buffer, b.byteOffset, b.byteLength);
    this._dispatch({ ...content, frame: { header: content, payload } });
  }
}

/**
 * A WidgetModel for a studio page inside a frame of the notebook's page: custom messages go to and come from the
 * parent window, which forwards them to and from the widget model (see widget.js).
 * @param {Window} [target] the window of the notebook's page
 * @returns {WidgetModel}
 */
export function parentModel(target = window.parent) {
  /** @type {Set<CustomListener>} */
  const listeners = new Set();
  window.addEventListener('message', (ev) => {
    if (ev.source !== target || !ev.data || ev.data.arap !== 'msg') return;
    for (const cb of listeners) cb(ev.data.content, ev.data.buffers);
  });
  return {
    send: (content, _callbacks, buffers) => target.postMessage({ arap: 'send', content, buffers: buffers ?? [] }, '*'),
    on: (_name, cb) => listeners.add(cb),
    off: (_name, cb) => listeners.delete(cb),
  };
}

/**
 * The studio session of this page: through the notebook's widget when the page is a widget's frame (the widget
 * sets `window.__ARAP_HOST__` to 'parent'), else the WebSocket of the server that served it.
 * @param {ConnectionHandlers} [handlers] what it tells (also given later: Connection.listen)
 * @returns {Connection}
 */
export function createConnection(handlers = {}) {
  if (/** @type {any} */ (window).__ARAP_HOST__ === 'parent') return new ModelConnection(parentModel(), handlers);
  return new Connection(defaultSocketUrl(), handlers);
}
