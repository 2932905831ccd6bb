// The session's edit history as the page knows it: whether undo and redo can step (the last state), which of them
// was asked for last, whether the state that answers the end of a drag is still awaited, and which server message
// a busy request waits for. Only this store writes its fields: the others tell it what happened through its methods.
import { CLIENT } from '../protocol.js';

/** @typedef {import('../protocol.js').StateServerMessage} StateServerMessage */
/** @typedef {typeof CLIENT.UNDO | typeof CLIENT.REDO} HistoryStep */

export class HistoryStore {
  #canUndo = false;
  #canRedo = false;
  /** @type {HistoryStep} */
  #lastHistory = CLIENT.UNDO;
  #awaitingState = false;
  /** @type {string|null} */
  #busyFor = null;

  /** The last state says that undo can step. */
  get canUndo() {
    return this.#canUndo;
  }

  /** The last state says that redo can step. */
  get canRedo() {
    return this.#canRedo;
  }

  /** @returns {HistoryStep} the last history request sent */
  get lastHistory() {
    return this.#lastHistory;
  }

  /** An end_drag whose state has not arrived yet. */
  get awaitingState() {
    return this.#awaitingState;
  }

  /** @returns {string|null} the type of the server message a busy request waits for (null: not busy) */
  get busyFor() {
    return this.#busyFor;
  }

  /** A drag ended (the gizmo's or the timeline's): the state that answers its end_drag is awaited. */
  dragEnded() {
    this.#awaitingState = true;
  }

  /** The server refused an end_drag: no state answers it. */
  endDragRefused() {
    this.#awaitingState = false;
  }

  /** The connection went away (lost, or refused by a full server): no state answers what was sent on it. */
  connectionLost() {
    this.#awaitingState = false;
  }

  /**
   * A request now waits for a server message of type `type` (null: nothing is waited for any longer).
   * @param {string|null} type
   */
  waitingFor(type) {
    this.#busyFor = type;
  }

  /**
   * An undo or a redo is asked for.
   * @param {HistoryStep} type
   */
  stepAsked(type) {
    this.#lastHistory = type;
  }

  /**
   * A state arrived: the history as it says. True when it answers the end of a drag.
   * @param {StateServerMessage} msg
   */
  stateArrived(msg) {
    const answered = this.#awaitingState;
    this.#awaitingState = false;
    this.take(msg);
    return answered;
  }

  /** @param {{can_undo?: boolean, can_redo?: boolean}} msg */
  take(msg) {
    this.#canUndo = !!msg.can_undo;
    this.#canRedo = !!msg.can_redo;
  }

  /** @param {HistoryStep} type */
  can(type) {
    return type === CLIENT.UNDO ? this.#canUndo : this.#canRedo;
  }

  /**
   * The step that goes over a state that is not the user's (restore.js isPinStep): the way the user went last, the
   * other one when that is not possible; null when neither is. A step found takes the state's history.
   * @param {StateServerMessage} msg
   * @returns {HistoryStep|null}
   */
  stepOver(msg) {
    const can = (/** @type {HistoryStep} */ t) => !!(t === CLIENT.UNDO ? msg.can_undo : msg.can_redo);
    const ahead = this.#lastHistory;
    const back = ahead === CLIENT.UNDO ? CLIENT.REDO : CLIENT.UNDO;
    const type = can(ahead) ? ahead : can(back) ? back : null;
    if (type !== null) this.take(msg);
    return type;
  }
}
