// Applies `vertices` frames to the viewer: full frames replace every position (and may list the movable
// vertices), subset frames overwrite only the movable vertices' positions, in place.
import { movableArray, vertexArray } from './protocol.js';

export class LivePose {
  constructor(viewer) {
    this.viewer = viewer;
    /** Movable vertices listed by the last full frame (Uint32Array), or null. */
    this.movable = null;
  }

  /** A new mesh: no list until the next full frame. */
  reset() {
    this.movable = null;
  }

  /**
   * Apply one `vertices` frame (decodeBinary's result); false when it does not fit the mesh shown (dropped).
   * @param {{header: object, payload: Uint8Array}} frame
   * @returns {boolean}
   */
  apply(frame) {
    const pos = vertexArray(frame);
    const { subset } = frame.header;
    if (!(subset >= 0)) {
      if (pos.length !== this.viewer.nVertices * 3) return false;
      this.movable = movableArray(frame);
      this.viewer.updatePositions(pos);
      return true;
    }
    const idx = this.movable;
    if (!idx || idx.length !== subset || pos.length !== 3 * subset) return false;
    this.viewer.updateSubset(idx, pos);
    return true;
  }
}
