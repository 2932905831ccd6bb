// The studio's events: what a piece built earlier tells pieces built after it. main.js builds the pieces in the
// order of what they need; where a piece must tell one that needs it (a cycle), it emits an event here, and main.js
// makes the later piece listen as soon as it is built.

/** @typedef {import('./protocol.js').ClientMessage} ClientMessage */

/**
 * The events, each with the arguments its listeners get.
 * - edited: the user changed the session (something to save): the session keeper hears it
 * - sent: a request went to the server (requests.js)
 * - shapeApplied: the newest shape received was drawn (livepose.js): `w` is what it answers, `ms` the JavaScript
 *   time spent applying it
 * - selectionChanged: the selection was replaced, or what hid its colours went away: it is drawn again (`full`: its
 *   panel list at once too)
 * @typedef {{
 *   edited: [],
 *   sent: [msg: ClientMessage],
 *   shapeApplied: [w: import('./livepose.js').Waiting, ms: number],
 *   selectionChanged: [full: boolean],
 * }} StudioEventMap
 */

/** @typedef {keyof StudioEventMap} StudioEvent */

export class StudioEvents {
  /** @type {Map<StudioEvent, ((...args: any[]) => void)[]>} */
  #listeners = new Map();

  /**
   * Call `listener` on each `name` event from now on (in the order listeners were added).
   * @template {StudioEvent} K
   * @param {K} name
   * @param {(...args: StudioEventMap[K]) => void} listener
   */
  on(name, listener) {
    const listeners = this.#listeners.get(name);
    if (listeners) listeners.push(listener);
    else this.#listeners.set(name, [listener]);
  }

  /**
   * Tell the listeners of `name`.
   * @template {StudioEvent} K
   * @param {K} name
   * @param {StudioEventMap[K]} args
   */
  emit(name, ...args) {
    for (const listener of this.#listeners.get(name) ?? []) listener(...args);
  }
}
