// Keeping the server's constraint set in step with the selection painted on the page. The page sends the whole
// selection (set_constraints) whenever it changed and the server does not hold it yet, then waits for the `state`
// that echoes it; until then drags are refused, since they would carry transforms for groups the server does not
// have. A state that echoes something else (undo, redo, a loaded document) replaces the selection, and an `error`
// that answers set_constraints leaves the selection refused until a later set is accepted. The server numbers only
// the non-empty handle groups: `groupMap` says which client group each server group is. All of this bookkeeping
// lives here, in one place, so that the gizmo, the timeline and the test hook read one answer to "does the server
// hold what is shown?".
import { CLIENT } from './protocol.js';
import { constraintsKey } from './selection.js';

/** @typedef {import('./selection.js').Selection} Selection */
/** @typedef {import('./selection.js').Constraints} Constraints */
/** @typedef {import('./selection.js').ConstraintsLike} ConstraintsLike */
/** @typedef {import('./protocol.js').StateServerMessage} StateServerMessage */
/** @typedef {import('./protocol.js').ErrorServerMessage} ErrorServerMessage */

/** The constraint set of a session without constraints (what the server holds after loading a mesh). */
const EMPTY = { roi: null, fixed: [], handle_groups: [] };

/**
 * What a state did to the constraint bookkeeping: `stepped` (it was a restore's pin step and another history step
 * went out instead: nothing else of it applies), `accepted` (it echoes the set sent), `held` (it holds the
 * selection shown), `adopted` (it replaced the selection) or `pending` (a set sent is still unanswered).
 * @typedef {'stepped'|'accepted'|'held'|'adopted'|'pending'} StateOutcome
 */

/**
 * What the page does when the server's set replaces the selection or a request's error stops holding.
 * @typedef {object} SyncHooks
 * @property {(c: ConstraintsLike) => void} replaceSelection put the server's set into the selection (and what
 *   depends on its groups, such as the mirror partners), before its groups are mapped
 * @property {() => void} selectionReplaced the selection was replaced and its groups mapped: show it
 * @property {() => void} requestErrorCleared the request error shown no longer holds (a later set was accepted)
 */

export class ConstraintSync {
  /** @type {string|null} constraintsKey of the last set_constraints not yet echoed by a state */
  sentKey = null;
  /** selection.version that set_constraints carried */
  sentVersion = -1;
  /** selection.version known to match the server's constraints */
  syncedVersion = -1;
  /** constraintsKey of the server's constraint set (last state) */
  serverKey = '';
  /** @type {number[][]} the transforms of the server's handle groups (last state): one per group a drag moves */
  serverTransforms = [];
  /** @type {number[][]} the handle groups of the server's constraint set (last state), point handles excluded */
  serverGroups = [];
  /** @type {number[]} server handle group k = client group groupMap[k] */
  groupMap = [];
  /** @type {string|null} why the server refused the last constraint set, until one is accepted */
  refusal = null;
  /** selection.version when a request's error was shown (cleared by a later accepted set) */
  errorVersion = -1;

  /**
   * @param {Selection} selection
   * @param {SyncHooks} hooks
   */
  constructor(selection, hooks) {
    this.selection = selection;
    this.hooks = hooks;
  }

  /** A set sent is not answered yet. */
  get pending() {
    return this.sentKey !== null;
  }

  /** A new mesh: the server holds no constraints and the (reset) selection has none either. */
  meshLoaded() {
    this.groupMap = [];
    this.serverTransforms = [];
    this.serverGroups = [];
    this.sentKey = null;
    this.syncedVersion = this.selection.version;
    this.refusal = null;
    this.errorVersion = -1;
    this.serverKey = constraintsKey(EMPTY);
  }

  /** True when the server holds the local selection (so drags refer to the groups shown). */
  selectionSynced() {
    if (this.selection.version === this.syncedVersion) return true;
    if (this.sentKey === null && constraintsKey(this.selection.toConstraints()) === this.serverKey) {
      this.syncedVersion = this.selection.version;
      return true;
    }
    return false;
  }

  /** A drag starts on a synced selection: it must carry one transform per server group. */
  dragStarts() {
    if (this.groupMap.length !== this.serverTransforms.length) this.groupMap = this.selection.toConstraints().groupMap;
  }

  /**
   * Whether the selection's set `c` needs no set_constraints: the server holds it already and none is under way
   * (e.g. a refused point handle was taken away again), unless `force`d (or it moves handles). Then drags carry its
   * groups from now on, not those of the set the server refused: the answer says whether they changed (the gizmo
   * then takes the server's transforms in the new numbering). Null: it must be sent (`sending`).
   * @param {Constraints} c
   * @param {boolean} force
   * @returns {{regrouped: boolean}|null}
   */
  held(c, force) {
    if (constraintsKey(c) !== this.serverKey || this.sentKey !== null || force) return null;
    const regrouped = c.groupMap.join() !== this.groupMap.join();
    this.groupMap = c.groupMap;
    this.syncedVersion = this.selection.version;
    return { regrouped };
  }

  /**
   * The selection's set `c` goes to the server now: its state is waited for.
   * @param {Constraints} c
   */
  sending(c) {
    this.groupMap = c.groupMap;
    this.sentKey = constraintsKey(c);
    this.sentVersion = this.selection.version;
  }

  /**
   * A state arrived: match its constraint set against what was sent. `stepOver(key)` is asked first, while nothing
   * is pending, whether the set is a restore's pin step that another history step goes over (true: it went out).
   * @param {StateServerMessage} msg
   * @param {(key: string) => boolean} stepOver
   * @returns {StateOutcome}
   */
  stateArrived(msg, stepOver) {
    /** @type {ConstraintsLike} */
    const c = msg.constraints || EMPTY;
    const key = constraintsKey(c);
    this.serverKey = key;
    if (this.sentKey === null && stepOver(key)) return 'stepped';
    /** @type {StateOutcome} */
    let outcome = 'pending';
    if (this.sentKey !== null && key === this.sentKey) {
      this.sentKey = null;
      this.syncedVersion = this.sentVersion;
      this.refusal = null;
      if (this.syncedVersion > this.errorVersion) this.hooks.requestErrorCleared(); // the error no longer holds
      outcome = 'accepted';
    } else if (this.sentKey === null && key === constraintsKey(this.selection.toConstraints())) {
      this.groupMap = this.selection.toConstraints().groupMap; // the server's groups are the ones shown
      outcome = 'held';
    } else if (this.sentKey === null) {
      // the server's constraints changed under us (undo/redo, loaded document): adopt them
      this.hooks.replaceSelection(c);
      this.groupMap = this.selection.toConstraints().groupMap;
      this.syncedVersion = this.selection.version;
      this.refusal = null;
      this.hooks.selectionReplaced();
      outcome = 'adopted';
    }
    this.serverTransforms = msg.transforms || [];
    this.serverGroups = c.handle_groups || [];
    return outcome;
  }

  /**
   * An error arrived: one that answers set_constraints refuses the set sent.
   * @param {ErrorServerMessage} msg
   */
  errorArrived(msg) {
    if (msg.request !== CLIENT.SET_CONSTRAINTS) return;
    this.sentKey = null;
    this.refusal = msg.message || msg.code;
  }

  /** A request's error was shown: it stays until a set made after it is accepted. */
  requestErrorShown() {
    this.errorVersion = this.selection.version;
  }
}
