// Autosave of the editing session in IndexedDB: written shortly after every change (at most once per delay), held
// while the session is being replaced or restored, and a warning before the page is left with edits.
import { deleteSession, putSession } from './sessiondb.js';

/**
 * A saved session: what snapshot.js captures, with the parts added here under their names.
 * @typedef {ReturnType<typeof import('./snapshot.js').captureSession> & {[part: string]: unknown}} Snapshot
 */

/** @type {Map<string, () => unknown>} */
const parts = new Map();

/**
 * Keep `capture()` under `name` in every snapshot saved from now on (nothing when it gives null or undefined); a
 * part makes the snapshot worth keeping (`edits`).
 * @param {string} name
 * @param {() => unknown} capture
 */
export function addSnapshotPart(name, capture) {
  parts.set(name, capture);
}

/**
 * @param {Snapshot} snap
 * @returns {Snapshot}
 */
function withParts(snap) {
  if (!snap || !parts.size) return snap;
  /** @type {Snapshot} */
  const out = { ...snap };
  for (const [name, capture] of parts) {
    const value = capture();
    if (value === null || value === undefined) continue;
    out[name] = value;
    out.edits = true;
  }
  return out;
}

export class Autosave {
  /**
   * @param {object} opts
   * @param {string} opts.id this page's record
   * @param {() => Snapshot} opts.capture the session now (see snapshot.js)
   * @param {number|(() => number)} [opts.delayMs] a number or a function giving one: the longest a change waits to
   *   be written
   * @param {((err: any) => void)|null} [opts.onError] told of a failed write (err: whatever IndexedDB rejected with)
   */
  constructor({ id, capture, delayMs = 500, onError = null }) {
    this.id = id;
    this.capture = () => withParts(capture());
    this.delayMs = delayMs;
    this.onError = onError;
    this.timer = null;
    this.writing = null; // promise of the write under way
    this.held = false;
    this.changes = 0; // changes seen
    this.savedChanges = 0; // changes covered by the last completed write
    this.saves = 0;
    this.meshKey = null; // source key of the mesh bytes stored with the record
    this.stored = false; // a record of this id may exist
    window.addEventListener('pagehide', () => this.flush());
  }

  /** Nothing waits to be written. */
  get idle() {
    return this.timer === null && this.writing === null && (this.held || this.savedChanges === this.changes);
  }

  /** Something changed: save soon. */
  touch() {
    this.changes++;
    this._schedule();
  }

  _schedule() {
    if (this.held || this.timer !== null) return;
    this.timer = setTimeout(() => {
      this.timer = null;
      this.flush();
    }, typeof this.delayMs === 'function' ? this.delayMs() : this.delayMs);
  }

  /** Write now (after a write under way); resolves when written. */
  async flush() {
    if (this.held) return;
    clearTimeout(this.timer);
    this.timer = null;
    if (this.writing) await this.writing.catch(() => {});
    if (this.held || this.writing) return;
    const changes = this.changes;
    try {
      await this._track(this._write(this.capture()));
      this.savedChanges = changes;
      this.saves++;
    } catch (err) {
      this.onError?.(err);
    }
    if (this.changes !== this.savedChanges) this._schedule();
  }

  /**
   * @param {Promise<void>} promise a write
   * @returns {Promise<void>}
   */
  _track(promise) {
    this.writing = promise;
    promise.catch(() => {}).finally(() => {
      if (this.writing === promise) this.writing = null;
    });
    return promise;
  }

  /**
   * @param {Snapshot} snap
   * @returns {Promise<void>}
   */
  async _write(snap) {
    if (!snap || !snap.edits || !snap.source) {
      if (!this.stored) return undefined;
      this.meshKey = null;
      await deleteSession(this.id);
      this.stored = false;
      return undefined;
    }
    const { bytes, ...source } = snap.source;
    /** @type {{id: string, key: number, bytes: ArrayBuffer}|null} */
    let mesh = null;
    if (source.kind === 'file' && source.key !== this.meshKey) mesh = { id: this.id, key: source.key, bytes };
    this.stored = true;
    await putSession({ ...snap, id: this.id, source }, mesh);
    if (mesh) this.meshKey = source.key;
    return undefined;
  }

  /**
   * Stop saving (the session shown is about to be replaced, e.g. after the connection was lost) and write the
   * current state one last time; returns that snapshot.
   */
  hold() {
    const snap = this.capture();
    clearTimeout(this.timer);
    this.timer = null;
    this.held = true;
    const previous = this.writing ?? Promise.resolve();
    this._track(previous.catch(() => {}).then(() => this._write(snap))).catch((err) => this.onError?.(err));
    return snap;
  }

  /**
   * Save under another id from now on, leaving the record of the old one as it is.
   * @param {string} id
   */
  renew(id) {
    this.id = id;
    this.meshKey = null;
    this.stored = false;
  }

  /** Save again from now on. */
  resume() {
    this.held = false;
    this.touch();
  }
}

/**
 * Ask before the page is left (reload, close, navigation) while `hasEdits()` is true.
 * @param {() => boolean} hasEdits
 */
export function warnBeforeUnload(hasEdits) {
  window.addEventListener('beforeunload', (e) => {
    if (!hasEdits()) return;
    e.preventDefault();
    e.returnValue = '';
  });
}
