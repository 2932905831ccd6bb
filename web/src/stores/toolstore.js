// What the user paints and with what: the role the tools paint, and the brush radius in each unit.

export class ToolStore {
  /** @type {string} the role painted ('roi', 'fixed', 'handle', 'erase', 'point' or 'stiffness') */
  role = 'handle';
  /** @type {{screen: number, world: number, [units: string]: number}} brush radius: pixels, or % of the model */
  brush = { screen: 24, world: 4 };
}
