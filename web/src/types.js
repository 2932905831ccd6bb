// Types shared by modules of the client (JSDoc only: nothing here runs). Typedefs are only ever appended.

/**
 * What the keyframe timeline (timeline.js) reads and calls.
 * @typedef {object} TimelineDeps
 * @property {() => string|null} blocked null when keyframes can be made and played, else why not
 * @property {() => number[][]} handleGroups the server's handle groups (vertex lists, point handles excluded), in
 *   drag order
 * @property {() => number[][]} transforms the current transform of every server group (handle groups, then point
 *   handles), column-major 4×4 each
 * @property {(g: number) => number[]} matrixOf the current transform of server group g
 * @property {() => ArrayLike<number>} positions the shown positions
 * @property {(g: number) => {indices: number[], weights: number[]|null}} anchor where server group g is: its
 *   vertices (a handle group), or a point handle's triangle corners and barycentric weights
 * @property {(transforms: number[][], key?: number) => void} drag drag every server group to these transforms (`key`:
 *   the keyframe whose pose they are, whose kept shape the server then shows)
 * @property {() => void} endDrag
 * @property {(msg: import('./protocol.js').ClientMessage) => boolean} send false when not sent
 * @property {(msg: import('./protocol.js').AnimationServerMessage & {frame?: {payload: Uint8Array}}) => string} download
 *   save the exported animation; the text to show
 * @property {() => void} changed something to autosave
 * @property {(text: string, kind: 'info'|'error') => void} say
 */

export {};
