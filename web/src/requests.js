// Sending the page's requests to the studio server, and what they leave waiting: the busy note until the message
// that answers them, the undo and redo steps (refused here when the last state says there is none), the keyframes
// carried over when apply makes the shape the new rest pose, a note when nothing can be sent, and the request
// errors shown until a later constraint set is accepted.
import { CLIENT, SERVER } from './protocol.js';

/** @typedef {import('./protocol.js').ClientMessage} ClientMessage */
/** @typedef {import('./stores/historystore.js').HistoryStep} HistoryStep */

/**
 * What sending reads and tells: a request sent is told as the studio's `sent` event (events.js), which the session
 * keeper and the timeline hear.
 * @typedef {object} RequestDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/historystore.js').HistoryStore} history
 * @property {import('./constraintsync.js').ConstraintSync} sync
 * @property {import('./connection.js').Connection} conn
 * @property {import('./panel.js').Panel} panel
 * @property {import('./gizmo.js').HandleGizmo} gizmo
 * @property {import('./events.js').StudioEvents} events
 */

export class Requests {
  /** @param {RequestDeps} deps */
  constructor(deps) {
    this.d = deps;
  }

  /**
   * Send a request; false (said on the status line) when not connected.
   * @param {ClientMessage} msg
   * @returns {boolean}
   */
  send(msg) {
    const { d } = this;
    if (!d.conn.send(msg)) {
      this.notConnected();
      return false;
    }
    d.events.emit('sent', msg);
    return true;
  }

  /** Say that nothing can be sent, unless the status bar already says why (connection lost, server full). */
  notConnected() {
    const { panel } = this.d;
    if (!panel.showing('connection')) panel.showStatus('Not connected to the studio server.', 'error');
  }

  /**
   * Say that the page waits (`text`; null: it no longer does) for a server message of type `forType`.
   * @param {string|null} text
   * @param {string} [forType]
   */
  setBusy(text, forType) {
    this.d.history.waitingFor(text ? /** @type {string} */ (forType) : null);
    this.d.panel.setBusy(text);
  }

  /**
   * Undo or redo; a step there is none of says so instead.
   * @param {HistoryStep} type
   */
  stepHistory(type) {
    const { d } = this;
    const undo = type === CLIENT.UNDO;
    if (!d.conn.open) {
      this.notConnected();
      return false;
    }
    // a drag or selection under way (its state not back yet) may make a step where the last state had none
    const pending = d.history.awaitingState || d.sync.pending || d.gizmo.dragging;
    if (d.mesh.ready && !pending && !d.history.can(type)) {
      d.panel.hint(undo ? 'Nothing to undo.' : 'Nothing to redo.', 2000);
      return false;
    }
    d.history.stepAsked(type);
    if (!this.send({ type })) return false;
    // busy until the state that answers it: the shape and the gizmo move back, so a drag must wait for them
    this.setBusy(undo ? 'Undoing…' : 'Redoing…', SERVER.STATE);
    return true;
  }
}

/**
 * Show the error of a request (or a refused drag) on the panel: it goes once a later constraint set is accepted.
 * @param {import('./constraintsync.js').ConstraintSync} sync
 * @param {import('./panel.js').Panel} panel
 * @param {string} text
 */
export function showRequestError(sync, panel, text) {
  sync.requestErrorShown();
  panel.showStatus(text, 'error', 0, 'request');
}
