// The side panel's read-outs: the connection indicator, the status bar (messages, hints, tagged so that they can
// be taken back once they no longer hold), the busy indicator, the statistics table, and the Shape line with the
// settling badge over the view. They only show what the studio tells them, unlike the panel's controls (panel.js),
// which extend this class and turn the user's input into actions.
import { byId as $ } from './dom.js';

/**
 * What the Shape line needs of a `settle` message.
 * @typedef {{status: string, iterations?: number, energy?: number|null}} SettleLike
 */

/** @param {number|null|undefined} v milliseconds */
function fmtMs(v) {
  if (v === null || v === undefined || !Number.isFinite(v)) return '–';
  return v >= 100 ? `${v.toFixed(0)} ms` : `${v.toFixed(1)} ms`;
}

/** @param {number|null|undefined} v */
export function fmtInt(v) {
  return typeof v === 'number' && Number.isFinite(v) ? v.toLocaleString('en-US') : '–';
}

/**
 * A count with its noun, singular for 1: "1 iteration", "3,000 iterations".
 * @param {number} n
 * @param {string} noun
 */
export function countOf(n, noun) {
  return `${fmtInt(n)} ${n === 1 ? noun : `${noun}s`}`;
}

/**
 * The Shape line's text for a `settle` message.
 * @param {SettleLike} msg
 */
export function settleText(msg) {
  const { iterations, energy: e } = msg;
  const n = typeof iterations === 'number' && Number.isFinite(iterations) ? iterations : 0;
  const after = n > 0 ? ` after ${countOf(n, 'iteration')}` : '';
  const energy = typeof e === 'number' && Number.isFinite(e) ? `, energy ${e.toPrecision(6)}` : '';
  switch (msg.status) {
    case 'settling':
      return `settling…${after}${energy}`;
    case 'settled':
      return `settled${after}${energy}`;
    case 'stopped': // a request interrupted it; it resumes once the requests are answered
      return `paused (editing)${after}${energy}`;
    case 'unconverged': // the server's iteration cap was reached
      return `not converged after ${countOf(n, 'iteration')}${energy}`;
    default:
      return `${msg.status}${after}${energy}`;
  }
}

export class PanelReadouts {
  constructor() {
    /** @type {ReturnType<typeof setTimeout>|undefined} hides the status bar's message */
    this._statusTimer = undefined;
    /** @type {ReturnType<typeof setTimeout>|undefined} hides the settling badge */
    this._badgeTimer = undefined;
  }

  /**
   * state: 'open', 'connecting', 'preparing' (connected, the server is not ready yet), 'closed', 'reconnecting' or
   * 'full' (the server refused this tab); retry: {attempt, delayMs} of the next try.
   * @param {string} state
   * @param {{attempt: number, delayMs: number}|null} [retry]
   */
  setConnection(state, retry = null) {
    const dot = $('conn-dot');
    dot.className = `dot ${state === 'open' ? 'ok' : state === 'connecting' || state === 'preparing' ? '' : 'bad'}`;
    /** @type {Object<string, string>} */
    const text = {
      open: 'connected', closed: 'disconnected', connecting: 'connecting…', reconnecting: 'reconnecting…',
      full: 'server full', preparing: 'preparing the solver…',
    };
    $('conn-text').textContent = text[state] ?? state;
    const next = retry ? `next try in ${(retry.delayMs / 1000).toFixed(1)} s` : '';
    $('conn-text').title = retry?.attempt ? `attempt ${retry.attempt}, ${next}` : next;
    // while reconnecting, the retries run by themselves; a full server is worth asking again after a tab closed
    $('btn-reconnect').hidden = state !== 'closed' && state !== 'full';
  }

  /**
   * The statistics table: the fields of `s` that are given (counts, timings, updates per second, latency).
   * @param {{n_vertices?: number, n_faces?: number, n_tetrahedra?: number, roi_size?: number, n_free?: number, factor_ms?: number|null,
   *   ms_per_iteration?: number|null, ups?: number, latency_ms?: number|null}} s
   */
  setStats(s) {
    const set = (/** @type {string} */ id, /** @type {string} */ v) => ($(id).textContent = v);
    if ('n_vertices' in s) set('st-vertices', fmtInt(s.n_vertices));
    if ('n_faces' in s) set('st-faces', fmtInt(s.n_faces));
    if ('n_tetrahedra' in s) {
      set('st-tetrahedra', fmtInt(s.n_tetrahedra));
      $('st-tetrahedra-row').hidden = !s.n_tetrahedra; // a solid's; a surface has none
    }
    if ('roi_size' in s) set('st-roi', fmtInt(s.roi_size));
    if ('n_free' in s) set('st-free', fmtInt(s.n_free));
    if ('factor_ms' in s) set('st-factor', fmtMs(s.factor_ms));
    if ('ms_per_iteration' in s) set('st-iter', fmtMs(s.ms_per_iteration));
    if ('ups' in s) set('st-ups', typeof s.ups === 'number' && Number.isFinite(s.ups) ? s.ups.toFixed(1) : '–');
    if ('latency_ms' in s) set('st-latency', fmtMs(s.latency_ms));
  }

  /**
   * The Shape line from a `settle` message: settling…, settled, paused (editing) or not converged, with the
   * iterations and the energy; `data-status` is the message's status.
   * @param {SettleLike} msg
   */
  setSettle(msg) {
    this._setShape(settleText(msg), msg.status);
    this._settleBadge(msg);
  }

  /**
   * The badge over the view: the settling's progress while the server iterates, then for a moment how it ended
   * (not for a shape that was settled already, after undo, redo or loading).
   * @param {SettleLike} msg
   */
  _settleBadge(msg) {
    const badge = $('settle-badge');
    clearTimeout(this._badgeTimer);
    const ran = msg.status === 'settling' || badge.dataset.status === 'settling' || badge.dataset.status === 'stopped';
    if (!ran) {
      badge.hidden = true;
      badge.dataset.status = '';
      return;
    }
    const text = settleText(msg);
    badge.textContent = text.charAt(0).toUpperCase() + text.slice(1);
    badge.dataset.status = msg.status;
    badge.hidden = false;
    if (msg.status !== 'settling' && msg.status !== 'stopped') {
      this._badgeTimer = setTimeout(() => {
        badge.hidden = true;
        badge.dataset.status = '';
      }, 2500);
    }
  }

  /** A new mesh: nothing is known of its shape's settling until the server says. */
  resetSettle() {
    this._setShape('–', '');
    clearTimeout(this._badgeTimer);
    $('settle-badge').hidden = true;
    $('settle-badge').dataset.status = '';
  }

  /** The connection was lost: a settling the line still shows as under way may never finish. */
  settleUnknown() {
    const status = $('st-settle').dataset.status;
    if (status === 'settling' || status === 'stopped') {
      this._setShape('unknown: the connection was lost while it settled', 'interrupted');
      $('settle-badge').hidden = true;
      $('settle-badge').dataset.status = '';
    }
  }

  /** @param {string} text @param {string} status */
  _setShape(text, status) {
    const cell = $('st-settle');
    cell.textContent = text;
    cell.dataset.status = status;
  }

  /**
   * Show a message in the status bar (kind 'info' or 'error'), hidden after `timeoutMs` (0: until replaced or
   * dismissed). `tag` names what it is about, so that `clearStatus(tag)` takes it away once it no longer holds.
   * @param {string} text
   */
  showStatus(text, kind = 'info', timeoutMs = 0, tag = '') {
    const bar = $('statusbar');
    bar.className = kind;
    bar.dataset.tag = tag;
    $('status-text').textContent = text;
    bar.hidden = false;
    clearTimeout(this._statusTimer);
    if (timeoutMs) this._statusTimer = setTimeout(() => this.hideStatus(), timeoutMs);
  }

  /**
   * True while the status bar shows a message tagged `tag` (see showStatus).
   * @param {string} tag
   */
  showing(tag) {
    return !$('statusbar').hidden && $('statusbar').dataset.tag === tag;
  }

  /**
   * A short hint (a key that does nothing now, and why): shown for `timeoutMs` unless the status bar holds an
   * error, which it must not hide.
   * @param {string} text
   */
  hint(text, timeoutMs = 3000) {
    if (!$('statusbar').hidden && $('statusbar').className === 'error') return;
    this.showStatus(text, 'info', timeoutMs, 'hint');
  }

  /**
   * Hide the status bar if it shows a message tagged `tag` (see showStatus).
   * @param {string} tag
   */
  clearStatus(tag) {
    if (!$('statusbar').hidden && $('statusbar').dataset.tag === tag) this.hideStatus();
  }

  hideStatus() {
    clearTimeout(this._statusTimer);
    $('statusbar').hidden = true;
  }

  /** @param {string|null} text what the studio is busy with, or null: not busy */
  setBusy(text) {
    $('busy').hidden = !text;
    if (text) $('busy-text').textContent = text;
  }
}
