// Restoring a saved session: the solver parameters, the mesh (a built-in model by name, or the mesh file's bytes
// uploaded again), the shape, then the selection. The shape comes back exactly: one constraint set holds every
// vertex that had moved at its saved position (the others fixed at rest), then the saved selection replaces it,
// referring to that shape (as any selection made after a drag does). That first set is an undo step on the server
// but not a state of the user's: `isPinStep` tells it, and the page steps over it when undo or redo lands there.
import { CLIENT, PARAMS } from './protocol.js';
import { constraintsKey } from './selection.js';
import { mismatch } from './snapshot.js';

/** @typedef {import('./autosave.js').Snapshot} Snapshot */

/** The density a picture is meshed at when it is opened (the server's `remesh` names the others). */
const OPENED_DENSITY = 'normal';

/** @type {((snap: Snapshot) => void)[]} */
const restored = [];

/**
 * Call `fn(snap)` whenever a saved session has been restored (its shape and selection are back on the server).
 * @param {(snap: Snapshot) => void} fn
 */
export function onSessionRestored(fn) {
  restored.push(fn);
}

export class SessionRestore {
  /**
   * @param {{send: (msg: import('./protocol.js').ClientMessage) => boolean,
   *   requestMesh: (source: import('./stores/meshstore.js').MeshSource) => boolean, applySelection: (snap: Snapshot) => void}} deps
   *   send(msg) → bool, requestMesh(source) → bool (load or upload it), applySelection(snap)
   *   (put the selection back and send it, even when the server seems to hold it already)
   */
  constructor(deps) {
    this.deps = deps;
    /**
     * `remeshed`: a picture's remesh was asked for (its source names a density).
     * @type {{snap: Snapshot, stage: 'mesh'|'constraints', onDone: (error: string|null) => void, remeshed?: boolean}|null}
     */
    this.active = null;
    /** @type {string|null} */
    this.pinKey = null; // constraintsKey of the set that put the shape back, while the server's history holds it
  }

  /**
   * True when the server's constraint set (its constraintsKey) is the one a restore put the shape back with.
   * @param {string} key
   */
  isPinStep(key) {
    return this.pinKey !== null && key === this.pinKey;
  }

  get busy() {
    return this.active !== null;
  }

  /**
   * Start restoring `snap` (its source with the file's bytes); onDone(error or null) is called once.
   * @param {Snapshot} snap
   * @param {(error: string|null) => void} onDone
   */
  start(snap, onDone) {
    const names = Object.keys(PARAMS).filter((k) => snap.params?.[k] !== undefined);
    const params = Object.fromEntries(names.map((k) => [k, snap.params[k]]));
    if (Object.keys(params).length) this.deps.send({ type: CLIENT.SET_PARAMS, ...params });
    this.active = { snap, stage: 'mesh', onDone };
    if (!this.deps.requestMesh(snap.source)) this._finish('not connected to the studio server');
  }

  /** The snapshot being restored (or null), and no longer waited for. */
  cancel() {
    const snap = this.active?.snap ?? null;
    this.active = null;
    return snap;
  }

  /**
   * A mesh arrived (`rest`: its positions): true when it was the restored one (its shape and selection have then
   * been sent).
   * @param {import('./protocol.js').MeshServerMessage} msg
   * @param {ArrayLike<number>} rest
   */
  meshArrived(msg, rest) {
    this.pinKey = null; // a new mesh starts a new history
    const a = this.active;
    if (!a || a.stage !== 'mesh') return false;
    const density = a.snap.source?.density;
    if (msg.picture && density && density !== OPENED_DENSITY && !a.remeshed) {
      // a picture meshed again at another density: meshed so again, its mesh is the saved one
      a.remeshed = true;
      if (!this.deps.send({ type: CLIENT.REMESH, density })) this._finish('not connected to the studio server');
      return true;
    }
    const problem = mismatch(a.snap, msg.n_vertices, msg.n_faces);
    if (problem) {
      this._finish(problem);
      return true;
    }
    a.stage = 'constraints';
    const shape = pinShape(a.snap.positions, rest);
    if (shape && !this.deps.send(shape)) {
      this._finish('not connected to the studio server');
      return true;
    }
    if (shape) this.pinKey = constraintsKey(shape);
    this.deps.applySelection(a.snap);
    return true;
  }

  /**
   * A state arrived; `synced`: the server holds the local selection.
   * @param {boolean} synced
   */
  stateArrived(synced) {
    if (this.active?.stage === 'constraints' && synced) this._finish(null);
  }

  /**
   * An error arrived: fatal to the restore when it answers one of its requests.
   * @param {import('./protocol.js').ErrorServerMessage} msg
   */
  errorArrived(msg) {
    const a = this.active;
    if (!a) return;
    /** @type {(string|null)[]} */
    const fatal = a.stage === 'mesh' ? [CLIENT.LOAD_BUILTIN, CLIENT.UPLOAD, CLIENT.REMESH] : [CLIENT.SET_CONSTRAINTS];
    if (fatal.includes(msg.request)) this._finish(msg.message || msg.code);
  }

  /** @param {string|null} error */
  _finish(error) {
    const a = this.active;
    this.active = null;
    a?.onDone(error);
    if (a && !error) for (const fn of restored) fn(a.snap);
  }
}

/**
 * set_constraints holding every vertex of `positions` that differs from `rest` there (others fixed), or null.
 * @param {ArrayLike<number>} positions
 * @param {ArrayLike<number>} rest
 * @returns {import('./protocol.js').SetConstraintsClientMessage|null}
 */
function pinShape(positions, rest) {
  /** @type {number[]} */
  const moved = [];
  /** @type {number[]} */
  const still = [];
  for (let i = 0, n = rest.length / 3; i < n; i++) {
    const same = positions[3 * i] === rest[3 * i] && positions[3 * i + 1] === rest[3 * i + 1]
      && positions[3 * i + 2] === rest[3 * i + 2];
    (same ? still : moved).push(i);
  }
  if (!moved.length) return null;
  const targets = moved.map((i) => [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]]);
  return { type: CLIENT.SET_CONSTRAINTS, roi: null, fixed: still, handle_groups: [moved], targets };
}
