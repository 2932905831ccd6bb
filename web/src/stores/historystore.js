// The session's edit history as the page knows it: whether undo and redo can step (the last state), which of them
// was asked for last, whether the state that answers the end of a drag is still awaited, and which server message
// a busy request waits for.
import { CLIENT } from '../protocol.js';

/** @typedef {import('../protocol.js').StateServerMessage} StateServerMessage */
/** @typedef {typeof CLIENT.UNDO | typeof CLIENT.REDO} HistoryStep */

export class HistoryStore {
  canUndo = false;
  canRedo = false;
  /** @type {HistoryStep} the last history request sent */
  lastHistory = CLIENT.UNDO;
  /** An end_drag whose state has not arrived yet. */
  awaitingState = false;
  /** @type {string|null} the type of the server message a busy request waits for (null: not busy) */
  busyFor = null;

  /**
   * A state arrived: the history as it says. True when it answers the end of a drag.
   * @param {StateServerMessage} msg
   */
  stateArrived(msg) {
    const answered = this.awaitingState;
    this.awaitingState = false;
    this.take(msg);
    return answered;
  }

  /** @param {{can_undo?: boolean, can_redo?: boolean}} msg */
  take(msg) {
    this.canUndo = !!msg.can_undo;
    this.canRedo = !!msg.can_redo;
  }

  /** @param {HistoryStep} type */
  can(type) {
    return type === CLIENT.UNDO ? this.canUndo : this.canRedo;
  }

  /**
   * The step that goes over a state that is not the user's (restore.js isPinStep): the way the user went last, the
   * other one when that is not possible; null when neither is. A step found takes the state's history.
   * @param {StateServerMessage} msg
   * @returns {HistoryStep|null}
   */
  stepOver(msg) {
    const can = (/** @type {HistoryStep} */ t) => !!(t === CLIENT.UNDO ? msg.can_undo : msg.can_redo);
    const ahead = this.lastHistory;
    const back = ahead === CLIENT.UNDO ? CLIENT.REDO : CLIENT.UNDO;
    const type = can(ahead) ? ahead : can(back) ? back : null;
    if (type !== null) this.take(msg);
    return type;
  }
}
