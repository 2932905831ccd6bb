// The colours of the vertex roles (region of interest, fixed anchors, handle groups, painted stiffness) and how a
// vertex's colour is made from its roles: the palette is shared by the viewer and the panel's legend, and the mixing
// over a mesh file's own colours or texture is a rule of its own, apart from the scene that draws the result.
import { stiffnessTint } from './stiffness.js';
import { OUTSIDE_BLEND, ROLE_BLEND } from './texture.js';

// Role colours in sRGB (as shown in the panel); the vertex colour attribute holds their linear values.
export const BASE_COLOR = [0.78, 0.79, 0.81];
const OUTSIDE_COLOR = [0.55, 0.56, 0.58];
const ROI_COLOR = [0.55, 0.74, 0.95];
export const FIXED_COLOR = [0.9, 0.3, 0.27];
export const STIFF_COLOR = [0.36, 0.16, 0.55];
export const GROUP_COLORS = [
  [1.0, 0.62, 0.1],
  [0.25, 0.78, 0.42],
  [0.66, 0.42, 0.96],
  [0.98, 0.84, 0.16],
  [0.15, 0.8, 0.84],
  [0.95, 0.4, 0.68],
  [0.58, 0.84, 0.2],
  [0.4, 0.52, 1.0],
];

/** @param {number} g */
export function groupColor(g) {
  return GROUP_COLORS[g % GROUP_COLORS.length];
}

/** @param {number[]} rgb */
export function cssColor(rgb) {
  return `rgb(${rgb.map((c) => Math.round(c * 255)).join(',')})`;
}

const srgbToLinear = (/** @type {number} */ c) => (c < 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);
const toLinear = (/** @type {number[]} */ rgb) => rgb.map(srgbToLinear);
/** The linear RGB of an unpainted vertex. */
export const BASE_LIN = toLinear(BASE_COLOR);
const OUTSIDE_LIN = toLinear(OUTSIDE_COLOR);
const ROI_LIN = toLinear(ROI_COLOR);
const FIXED_LIN = toLinear(FIXED_COLOR);
const GROUP_LIN = GROUP_COLORS.map(toLinear);
const STIFF_LIN = toLinear(STIFF_COLOR);

/**
 * Colour the vertices by role into `c` (linear RGB, 3 per vertex): roi (Uint8Array, or null: no region), role
 * (Int16Array: 0 none, 1 fixed, 2+g handle g); `stiff` (per-vertex stiffness, or null) tints painted vertices
 * towards purple by `stiffStrength` (0..1) of their tint. Over the file's colours (`file`, linear RGB) the roles
 * are mixed in; with `tint` (RGBA per vertex) the colour and its blend over the texture are written there too.
 * @param {import('three').TypedArray} c
 * @param {Float32Array|null} tint
 * @param {ArrayLike<number>|null} file
 * @param {Uint8Array|null} roi
 * @param {Int16Array} role
 * @param {ArrayLike<number>|null} stiff
 * @param {number} stiffStrength
 */
export function fillRoleColors(c, tint, file, roi, role, stiff, stiffStrength) {
  for (let i = 0, n = role.length; i < n; i++) {
    const r = role[i];
    let rgb;
    let blend = ROLE_BLEND;
    if (r === 1) rgb = FIXED_LIN;
    else if (r >= 2) rgb = GROUP_LIN[(r - 2) % GROUP_LIN.length];
    else if (roi !== null && !roi[i]) {
      rgb = OUTSIDE_LIN;
      blend = OUTSIDE_BLEND;
    } else {
      rgb = roi !== null ? ROI_LIN : BASE_LIN;
      blend = 0;
    }
    const t = stiff && stiff[i] !== 1 ? stiffStrength * stiffnessTint(stiff[i]) : 0;
    let x = rgb[0] + t * (STIFF_LIN[0] - rgb[0]);
    let y = rgb[1] + t * (STIFF_LIN[1] - rgb[1]);
    let z = rgb[2] + t * (STIFF_LIN[2] - rgb[2]);
    if (blend === 0 && t > 0 && (tint || file)) { // unpainted but stiff: the stiffness colour over the surface
      x = STIFF_LIN[0];
      y = STIFF_LIN[1];
      z = STIFF_LIN[2];
      blend = t;
    }
    if (tint) {
      tint[4 * i] = x;
      tint[4 * i + 1] = y;
      tint[4 * i + 2] = z;
      tint[4 * i + 3] = blend;
    }
    if (file) {
      x = file[3 * i] + blend * (x - file[3 * i]);
      y = file[3 * i + 1] + blend * (y - file[3 * i + 1]);
      z = file[3 * i + 2] + blend * (z - file[3 * i + 2]);
    }
    c[3 * i] = x;
    c[3 * i + 1] = y;
    c[3 * i + 2] = z;
  }
}
