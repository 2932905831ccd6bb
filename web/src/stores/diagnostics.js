// What the page records for tests and debugging: the errors it showed or was sent, the messages received, the
// JavaScript time spent applying frames and showing meshes, and the wall-clock steps of the last upload.

/** @typedef {{code: string, message: string, request: string|null}} ErrorRecord */
/** @typedef {'chosen'|'read'|'sent'|'received'|'shown'|'drawn'} UploadStep */

/** Wall-clock time now, in ms since the epoch. */
const wallClock = () => performance.timeOrigin + performance.now();

export class Diagnostics {
  /** @type {ErrorRecord[]} */
  errors = [];
  /** Messages received from the server. */
  messages = 0;
  /** @type {number[]} JavaScript ms spent applying each vertices frame applied (the newest 256; drawing excluded) */
  frameMs = [];
  /** JavaScript ms spent showing the last mesh message (drawing excluded). */
  meshMs = NaN;
  /** @type {Partial<Record<UploadStep, number>>} wall-clock times (ms since the epoch) of the last upload's steps */
  uploadAt = {};

  /**
   * @param {string} code
   * @param {string} message
   * @param {string|null} request
   */
  error(code, message, request) {
    this.errors.push({ code, message, request });
  }

  /** @param {number} ms */
  frameApplied(ms) {
    this.frameMs.push(ms);
    if (this.frameMs.length > 256) this.frameMs.shift();
  }

  /** An upload starts over: a file was chosen. */
  uploadChosen() {
    this.uploadAt = { chosen: wallClock() };
  }

  /** @param {UploadStep} step */
  mark(step) {
    this.uploadAt[step] = wallClock();
  }
}
