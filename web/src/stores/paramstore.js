// The solver parameters the server uses, as its last welcome or state said (what the panel's controls go back to
// when the server refuses a change, and what a saved session keeps). Only this store writes them.

/** @typedef {import('../protocol.js').StateServerMessage['params']} SolverParams */

export class ParamStore {
  /** @type {Partial<SolverParams>} */
  #values = {};

  /** @returns {Readonly<Partial<SolverParams>>} */
  get values() {
    return this.#values;
  }

  /**
   * Take the parameters of a welcome or a state (absent: they stay).
   * @param {SolverParams|undefined|null} params
   */
  take(params) {
    if (params) this.#values = { ...params };
  }
}
