// Applies `vertices` frames to the viewer at the rate the page draws: a frame received is kept until the next
// animation frame, and a newer one replaces it, so the page never works through frames it would not show. Full
// frames replace every position (and may list the movable vertices); subset frames carry only the movable
// vertices' positions, which a full frame still waiting to be applied takes in place, so that it stays the newest
// shape and the subset frames after it keep the list it brought.
import { movableArray, vertexArray } from './frames.js';

/** Longest wait (ms) for an animation frame before a waiting frame is applied anyway (a page drawn rarely). */
const LATEST_APPLY_MS = 250;

/** @typedef {import('./protocol.js').VerticesServerMessage} VerticesServerMessage */

/**
 * @typedef {object} Waiting
 * @property {Float32Array} positions every position (full) or the movable vertices' (subset)
 * @property {Uint32Array|null} movable the subset's vertices, in its order; null for a full frame
 * @property {VerticesServerMessage} msg the newest message taken in (its header fields)
 * @property {number} seq the newest request sequence number among the frames taken in (-1: none)
 * @property {VerticesServerMessage|null} solved the newest message taken in that came from a solve (iterations > 0), or null
 * @property {number} frames how many frames it stands for
 */

export class LivePose {
  /**
   * @param {import('./viewer.js').Viewer} viewer
   * @param {(w: Waiting, ms: number) => void} [onApplied] called after a waiting frame was applied (`ms`: the
   *   JavaScript time the viewer took to apply it, drawing excluded)
   */
  constructor(viewer, onApplied = () => {}) {
    this.viewer = viewer;
    this.onApplied = onApplied;
    /** @type {Uint32Array|null} movable vertices listed by the last full frame received, or null */
    this.movable = null;
    /** @type {Waiting|null} the newest shape received and not yet applied */
    this.waiting = null;
    this.received = 0; // frames taken in since the page loaded
    this.applied = 0; // of which applied (the others were replaced by newer ones before being drawn)
    this._raf = 0;
    this._timer = 0;
  }

  /** A new mesh: no list until the next full frame, and nothing waiting of the old one. */
  reset() {
    this.movable = null;
    this._cancel();
    this.waiting = null;
  }

  /** True while a frame received waits to be applied. */
  get pending() {
    return this.waiting !== null;
  }

  /**
   * Take in one `vertices` frame (decodeBinary's result, with its message's fields in `msg`); it is applied at the
   * next animation frame unless a newer one replaces it first. False when it does not fit the mesh shown (dropped).
   * @param {{header: VerticesServerMessage, payload: Uint8Array}} frame
   * @param {VerticesServerMessage} [msg]
   * @returns {boolean}
   */
  receive(frame, msg = frame.header) {
    const pos = vertexArray(frame);
    const { subset } = frame.header;
    const seq = Number.isInteger(msg.seq) && msg.seq >= 0 ? msg.seq : -1;
    const solved = msg.iterations > 0 ? msg : null;
    const before = this.waiting;
    const carried = before ? { seq: seq >= 0 ? seq : before.seq, solved: solved ?? before.solved,
      frames: before.frames + 1 } : { seq, solved, frames: 1 };
    if (!(subset >= 0)) {
      if (pos.length !== this.viewer.nVertices * 3) return false;
      this.movable = movableArray(frame);
      this.waiting = { positions: pos, movable: null, msg, ...carried };
    } else {
      const idx = this.movable;
      if (!idx || idx.length !== subset || pos.length !== 3 * subset) return false;
      if (before && before.movable === null) {
        // a full frame not applied yet: it takes the newer positions and stays a full frame
        const all = before.positions;
        for (let k = 0, o = 0; k < idx.length; k++, o += 3) {
          const i = 3 * idx[k];
          all[i] = pos[o];
          all[i + 1] = pos[o + 1];
          all[i + 2] = pos[o + 2];
        }
        this.waiting = { positions: all, movable: null, msg, ...carried };
      } else {
        this.waiting = { positions: pos, movable: idx, msg, ...carried };
      }
    }
    this.received++;
    this._schedule();
    return true;
  }

  /** Apply the waiting frame now, if any (before a message whose handling reads the shape shown). */
  flush() {
    this._cancel();
    const w = this.waiting;
    if (!w) return;
    this.waiting = null;
    const t0 = performance.now();
    if (w.movable === null) this.viewer.updatePositions(w.positions);
    else this.viewer.updateSubset(w.movable, w.positions);
    this.applied++;
    this.onApplied(w, performance.now() - t0);
  }

  _schedule() {
    if (this._raf) return;
    this._raf = requestAnimationFrame(() => {
      this._raf = 0;
      this.flush();
    });
    this._timer = window.setTimeout(() => this.flush(), LATEST_APPLY_MS);
  }

  _cancel() {
    if (this._raf) cancelAnimationFrame(this._raf);
    clearTimeout(this._timer);
    this._raf = 0;
    this._timer = 0;
  }
}
