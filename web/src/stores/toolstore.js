// What the user paints and with what: the role the tools paint, and the brush radius in each unit. Only this store
// writes its fields: the others tell it what the user chose through its methods.

/** @typedef {{screen: number, world: number, [units: string]: number}} BrushRadii */

export class ToolStore {
  #role = 'handle';
  /** @type {BrushRadii} */
  #brush = { screen: 24, world: 4 };

  /** The role painted ('roi', 'fixed', 'handle', 'erase', 'point' or 'stiffness'). */
  get role() {
    return this.#role;
  }

  /** @returns {Readonly<BrushRadii>} brush radius: pixels, or % of the model */
  get brush() {
    return this.#brush;
  }

  /**
   * The user chose the role to paint.
   * @param {string} role
   */
  roleChosen(role) {
    this.#role = role;
  }

  /**
   * The user sized the brush in `units` ('screen': pixels, 'world': % of the model).
   * @param {string} units
   * @param {number} radius
   */
  brushSized(units, radius) {
    this.#brush[units] = radius;
  }
}
