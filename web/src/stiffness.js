// Painted stiffness: the per-vertex cell weights (1 = unpainted, Infinity = rigid) in the form of the protocol and of
// constraints files ([{vertices, value}], "rigid" for Infinity), the brush's strength scale and the overlay colours.

/** Strongest finite value of the brush; its slider runs from 1 to this on a log scale. */
export const MAX_STIFFNESS = 100;

/**
 * Per-vertex stiffness as `[{vertices, value}]` in the server's order (values ascending, rigid last; vertices
 * ascending), or null when every vertex is at 1.
 * @param {Float64Array} stiff
 * @returns {Array<{vertices: number[], value: number|"rigid"}>|null}
 */
export function stiffnessToJson(stiff) {
  /** @type {Map<number, number[]>} */
  const byValue = new Map();
  for (let i = 0; i < stiff.length; i++) {
    const v = stiff[i];
    if (v === 1) continue;
    let list = byValue.get(v);
    if (!list) byValue.set(v, (list = []));
    list.push(i);
  }
  if (!byValue.size) return null;
  return [...byValue].sort((a, b) => a[0] - b[0]).map(([v, vertices]) => ({
    vertices,
    value: v === Infinity ? 'rigid' : v,
  }));
}

/**
 * Per-vertex stiffness (n,) from `[{vertices, value}]` (or null: all 1); bad entries are skipped.
 * @param {any} groups JSON as read from a constraints document or a saved session: checked here, entry by entry
 * @param {number} n vertices
 * @returns {Float64Array}
 */
export function stiffnessFromJson(groups, n) {
  const out = new Float64Array(n).fill(1);
  if (!Array.isArray(groups)) return out;
  for (const g of groups) {
    const value = g?.value === 'rigid' ? Infinity : g?.value;
    if (typeof value !== 'number' || !(value > 0) || !Array.isArray(g.vertices)) continue;
    for (const i of g.vertices) if (Number.isInteger(i) && i >= 0 && i < n) out[i] = value;
  }
  return out;
}

/**
 * A canonical string of painted stiffness (null and [] are the same: nothing painted).
 * @param {{vertices: number[], value: number|string}[]|null} [groups]
 */
export function stiffnessKey(groups) {
  if (!Array.isArray(groups) || !groups.length) return '';
  return groups.map((g) => `${g.value}=${g.vertices.join(',')}`).join('|');
}

/**
 * The brush value of a slider position 0..100 (log scale from 1 to MAX_STIFFNESS, two significant digits).
 * @param {number} position
 */
export function sliderToStiffness(position) {
  const v = MAX_STIFFNESS ** (Math.min(100, Math.max(0, position)) / 100);
  return Number(v.toPrecision(2));
}

/**
 * The slider position 0..100 of a stiffness value.
 * @param {number} value
 */
export function stiffnessToSlider(value) {
  return Math.round((100 * Math.log(Math.max(1, value))) / Math.log(MAX_STIFFNESS));
}

/**
 * How strongly a stiffness value tints the surface: 0 at 1, rising with its logarithm, 1 when rigid.
 * @param {number} value
 */
export function stiffnessTint(value) {
  if (value === Infinity) return 1;
  if (!(value > 1)) return 0;
  return Math.min(1, 0.25 + (0.6 * Math.log(value)) / Math.log(MAX_STIFFNESS));
}

/**
 * Label of a stiffness value.
 * @param {number} value
 */
export function stiffnessLabel(value) {
  return value === Infinity ? 'rigid' : `×${value}`;
}
