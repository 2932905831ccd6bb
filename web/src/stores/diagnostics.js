// What the page records for tests and debugging: the errors it showed or was sent, the messages received, the
// JavaScript time spent applying frames and showing meshes, and the wall-clock steps of the last upload.
// Only this store writes its fields: the others tell it what happened through its methods.

/** @typedef {{code: string, message: string, request: string|null}} ErrorRecord */
/** @typedef {'chosen'|'read'|'sent'|'received'|'shown'|'drawn'} UploadStep */

/** Wall-clock time now, in ms since the epoch. */
const wallClock = () => performance.timeOrigin + performance.now();

export class Diagnostics {
  /** @type {ErrorRecord[]} */
  #errors = [];
  #messages = 0;
  /** @type {number[]} */
  #frameMs = [];
  #meshMs = NaN;
  /** @type {Partial<Record<UploadStep, number>>} */
  #uploadAt = {};

  /** @returns {readonly Readonly<ErrorRecord>[]} the errors shown or sent, oldest first */
  get errors() {
    return this.#errors;
  }

  /** Messages received from the server. */
  get messages() {
    return this.#messages;
  }

  /** @returns {readonly number[]} JavaScript ms spent applying each vertices frame (the newest 256; no drawing) */
  get frameMs() {
    return this.#frameMs;
  }

  /** JavaScript ms spent showing the last mesh message (drawing excluded). */
  get meshMs() {
    return this.#meshMs;
  }

  /** @returns {Readonly<Partial<Record<UploadStep, number>>>} when the last upload's steps happened (epoch ms) */
  get uploadAt() {
    return this.#uploadAt;
  }

  /** A message of the server arrived. */
  messageReceived() {
    this.#messages++;
  }

  /**
   * @param {string} code
   * @param {string} message
   * @param {string|null} request
   */
  error(code, message, request) {
    this.#errors.push({ code, message, request });
  }

  /** @param {number} ms */
  frameApplied(ms) {
    this.#frameMs.push(ms);
    if (this.#frameMs.length > 256) this.#frameMs.shift();
  }

  /**
   * A mesh message was shown, in `ms` of JavaScript.
   * @param {number} ms
   */
  meshShown(ms) {
    this.#meshMs = ms;
  }

  /** An upload starts over: a file was chosen. */
  uploadChosen() {
    this.#uploadAt = { chosen: wallClock() };
  }

  /**
   * An upload's step happened: now, or at `at` (ms since the epoch).
   * @param {UploadStep} step
   * @param {number} [at]
   */
  mark(step, at = wallClock()) {
    this.#uploadAt[step] = at;
  }
}
