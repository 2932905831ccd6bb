// Keyframe timeline: the handle groups' and point handles' transforms stored at a few times, a time bar with a marker
// per keyframe, a playhead to scrub (or a time typed), playback at the animation's frame rate, and the export of the
// solved animation as a GLB (for a picture also as an animated GIF or WebP, or PNG frames).
// A keyframe holds one column-major 4×4 per group of the server's constraint set (handle groups, then point handles)
// and the easing of the motion to the next keyframe; how the groups move between keyframes is keyframes.js's. When a
// keyframe is made the server keeps the shape shown (keep_shape, under the keyframe's number): a drag at that
// keyframe's pose, and the export's frame at its time, give that shape back instead of solving the pose again (which
// could end in another shape).
// Scrubbing and playback send the interpolated transforms as drags, so the shape follows live; the connection keeps
// at most one drag unanswered, so a slow server drops frames instead of queueing them.
import * as THREE from 'three';
import { byId, byIdAs } from './dom.js';
import { EASINGS, frameCount, interpolate, rebased } from './keyframes.js';
import { CLIENT, SERVER } from './protocol.js';

export { ease, EASINGS, frameCount, interpolate, polar, turn } from './keyframes.js';

/** @typedef {import('./keyframes.js').Keyframe} Keyframe */
/** @typedef {import('./protocol.js').ExportAnimationClientMessage} ExportAnimationClientMessage */
/** @typedef {import('./protocol.js').ServerMessage} ServerMessage */

/** Most frames an export may have (the server refuses more). */
export const MAX_EXPORT_FRAMES = 600;

export class Timeline {
  /**
   * @param {import('./types.js').TimelineDeps} deps what it reads (blocked, handleGroups, transforms, matrixOf,
   *   positions, anchor) and calls (drag, endDrag, send, download, changed, say)
   */
  constructor(deps) {
    this.deps = deps;
    /** @type {Keyframe[]} */
    this.keys = [];
    /** @type {number[][]|null} */
    this.pivots = null; // per handle group, in the pose of the constraint set the keyframes refer to
    this.timeMs = 0;
    this.durationMs = 2000;
    this.fps = 24;
    this.playing = false;
    this.scrubbing = false;
    this.dragsSent = 0; // drags the timeline sent (scrub and playback)
    this.framesShown = 0; // playback frames that reached the server
    this.exporting = false;
    this.exportNote = '';
    this._frame = -1;
    this._raf = 0;
    this._moved = false; // drags sent since the last end_drag
    this._nextId = 1; // the number of the next keyframe (keep_shape's key)
    /** @type {Keyframe|null} the keyframe made last, while the shape it keeps may still be settling */
    this._keeping = null;
    /** @type {ExportAnimationClientMessage['format']} */
    this.format = 'glb';
    /** @type {number|null} where a press on a marker started (a scrub begins once the pointer leaves it) */
    this._pressX = null;

    this.bar = byId('tl-bar');
    this.markers = byId('tl-markers');
    this.playhead = byId('tl-playhead');
    this.bar.addEventListener('pointerdown', (e) => this._pointerDown(e));
    this.bar.addEventListener('pointermove', (e) => this._pointerMove(e));
    this.bar.addEventListener('pointerup', (e) => this._pointerUp(e));
    this.bar.addEventListener('pointercancel', (e) => this._pointerUp(e));
    byId('btn-tl-add').addEventListener('click', () => this.addKeyframe());
    byId('btn-tl-delete').addEventListener('click', () => this.deleteKeyframe());
    byId('btn-tl-play').addEventListener('click', () => (this.playing ? this.pause() : this.play()));
    byId('btn-tl-export').addEventListener('click', () => this.exportAnimation());
    const duration = byIdAs('tl-duration', HTMLInputElement);
    const fps = byIdAs('tl-fps', HTMLInputElement);
    duration.addEventListener('change', () => this.setDuration(Number(duration.value)));
    fps.addEventListener('change', () => this.setFps(Number(fps.value)));
    const at = byIdAs('tl-time-input', HTMLInputElement);
    at.addEventListener('change', () => this.typedTime(Number(at.value)));
    const keyTime = byIdAs('tl-key-time', HTMLInputElement);
    keyTime.addEventListener('change', () => this.moveKeyframe(Number(keyTime.value)));
    const easing = byIdAs('tl-easing', HTMLSelectElement);
    easing.addEventListener('change', () => this.setEasing(easing.value));
    const format = byIdAs('tl-format', HTMLSelectElement);
    format.addEventListener('change', () => {
      this.format = /** @type {ExportAnimationClientMessage['format']} */ (format.value);
    });
    this.render();
  }

  // ------------------------------------------------------------------ keyframes

  /** Store the groups' current transforms at the playhead (replacing a keyframe at that time, keeping its
   * easing), and have the server keep the shape shown as this keyframe's. */
  addKeyframe() {
    const why = this.deps.blocked();
    if (why) return this.deps.say(`Cannot add a keyframe: ${why}.`, 'error');
    this.pause();
    const all = this.deps.transforms();
    if (this.keys.length && this.keys[0].transforms.length !== all.length) {
      this.keys = []; // made for other groups
      this.pivots = null;
    }
    if (!this.pivots) this.pivots = all.map((_, g) => this._pivot(g));
    const at = this.keys.findIndex((k) => k.ms >= this.timeMs);
    const replaced = at >= 0 && this.keys[at].ms === this.timeMs ? this.keys[at] : null;
    const key = { ms: this.timeMs, transforms: all.map((m) => m.slice()), easing: replaced?.easing ?? 'linear',
      id: this._nextId++, shape: Float32Array.from(this.deps.positions()) };
    this._keeping = key; // the server settles the shape before it keeps it: settled() takes the settled one
    if (replaced) this.keys[at] = key;
    else if (at >= 0) this.keys.splice(at, 0, key);
    else this.keys.push(key);
    this.deps.send({ type: CLIENT.KEEP_SHAPE, key: key.id });
    this._changed();
    return undefined;
  }

  /** The shape shown has settled: the keyframe made last keeps it as its shape (as the server did), unless its
   * handles have moved away from that keyframe's pose since. */
  settled() {
    const key = this._keeping;
    this._keeping = null;
    if (!key || !this.keys.includes(key)) return;
    const now = this.deps.transforms();
    const same = now.length === key.transforms.length
      && now.every((m, g) => m.every((v, i) => Math.abs(v - key.transforms[g][i]) <= 1e-9 * (1 + Math.abs(v))));
    if (!same) return;
    key.shape = Float32Array.from(this.deps.positions());
    this._changed();
  }

  /** Give the server back the shapes of the keyframes (after a restore: the session that kept them is gone). */
  _giveShapesBack() {
    const n = this.deps.positions().length;
    for (const key of this.keys) {
      const shape = key.shape;
      if (!shape || shape.length !== n || key.id === undefined) continue;
      /** @type {number[][]} */
      const points = [];
      for (let i = 0; i < n; i += 3) points.push([shape[i], shape[i + 1], shape[i + 2]]);
      this.deps.send({ type: CLIENT.KEEP_SHAPE, key: key.id, shape: points });
    }
  }

  /** The keyframe at the playhead, or null. */
  current() {
    return this.keys.find((k) => k.ms === this.timeMs) ?? null;
  }

  /** The easing of the keyframe at the playhead (how the handles move from it to the next). @param {string} easing */
  setEasing(easing) {
    const key = this.current();
    if (!key || !EASINGS.includes(easing)) return this.render();
    key.easing = easing;
    this._changed();
    return undefined;
  }

  /** A time typed for the playhead, in seconds. @param {number} seconds */
  typedTime(seconds) {
    if (!Number.isFinite(seconds) || seconds < 0) return this.render();
    if (seconds * 1000 > this.durationMs) this.setDuration(seconds);
    this.goTo(seconds * 1000);
    return undefined;
  }

  /** Move the keyframe at the playhead to a typed time (seconds); the playhead follows it. @param {number} seconds */
  moveKeyframe(seconds) {
    const key = this.current();
    const ms = Math.round(seconds * 1000);
    if (!key || !Number.isFinite(seconds) || ms < 0) return this.render();
    if (this.keys.some((k) => k !== key && k.ms === ms)) {
      this.deps.say(`There is a keyframe at ${(ms / 1000).toFixed(3)} s already.`, 'error');
      return this.render();
    }
    key.ms = ms;
    this.keys.sort((a, b) => a.ms - b.ms);
    if (ms > this.durationMs) this.durationMs = ms;
    this.timeMs = ms;
    this._changed();
    return undefined;
  }

  /** Delete the keyframe at the playhead. */
  deleteKeyframe() {
    const at = this.keys.findIndex((k) => k.ms === this.timeMs);
    if (at < 0) return this.deps.say('No keyframe at the playhead: click a marker to go to one.', 'info');
    this.keys.splice(at, 1);
    if (!this.keys.length) this.pivots = null;
    this._changed();
    return undefined;
  }

  /** Server group g's pivot in the pose its transform applies to: the centroid of a handle group's vertices, or a
   * point handle's point (which then moves on a straight line between keyframes, as the server's point targets do).
   * @param {number} g */
  _pivot(g) {
    const P = this.deps.positions();
    const { indices, weights } = this.deps.anchor(g);
    const c = [0, 0, 0];
    let total = 0;
    indices.forEach((i, k) => {
      const w = weights ? weights[k] : 1;
      total += w;
      for (let d = 0; d < 3; d++) c[d] += w * P[3 * i + d];
    });
    const v = new THREE.Vector3(c[0], c[1], c[2]).divideScalar(total || 1);
    return v.applyMatrix4(new THREE.Matrix4().fromArray(this.deps.matrixOf(g)).invert()).toArray();
  }

  /**
   * The constraint set is replaced by one whose pose is the current shape (its transforms back to identity):
   * keyframes follow, each transform composed with the inverse of the current one (`current`: one per server group).
   * @param {number[][]} current @param {number} nHandleGroups */
  rebase(current, nHandleGroups) {
    if (!this.keys.length) return;
    if (this.keys[0].transforms.length !== nHandleGroups) {
      this.clear();
      this.deps.say('The keyframes were cleared: the handle groups changed.', 'info');
      return;
    }
    this.keys = this.keys.map((k) => ({ ...k, transforms: k.transforms.map((m, g) => rebased(m, current[g])) }));
    this.pivots = this.pivots?.map((p, g) => new THREE.Vector3(...p).applyMatrix4(new THREE.Matrix4()
      .fromArray(current[g])).toArray()) ?? null;
    this._changed();
  }

  /**
   * Keyframes read from a constraints document whose handle groups were just sent with the positions their
   * transforms apply to (`pivots`: per group, the centroid of those positions).
   * @param {Keyframe[]} keys @param {number[][]} pivots */
  load(keys, pivots) {
    this.pause();
    const n = pivots.length;
    if (keys.some((k) => k.transforms.length !== n)) {
      this.deps.say(`The document's keyframes hold transforms for another number of handle groups than its ${n}; `
        + 'they are not loaded.', 'error');
      return;
    }
    this.keys = keys.map((k) => ({ ...k, id: this._nextId++ })); // no shape kept for them yet
    this.pivots = pivots;
    this.durationMs = Math.max(this.durationMs, keys[keys.length - 1].ms);
    this.timeMs = keys[0].ms;
    this.deps.say(`Loaded ${keys.length} keyframe${keys.length > 1 ? 's' : ''}; the handles start where the `
      + 'keyframes\' transforms apply.', 'info');
    this._changed();
  }

  clear() {
    this.pause();
    if (!this.keys.length) return;
    this.keys = [];
    this.pivots = null;
    this._changed();
  }

  /** What autosave keeps: the keyframes and the transforms they were made against (`base`, per handle group). */
  snapshot() {
    if (!this.keys.length) return null;
    const n = this.keys[0].transforms.length;
    return {
      keys: this.keys.map((k) => ({ ...k, transforms: k.transforms.map((m) => m.slice()) })),
      pivots: this.pivots?.map((p) => p.slice()) ?? null,
      base: this.deps.transforms().slice(0, n).map((m) => m.slice()),
      timeMs: this.timeMs,
      durationMs: this.durationMs,
      fps: this.fps,
    };
  }

  /**
   * Put back a snapshot once the session it belongs to is restored (its shape is the pose of the new set).
   * @param {ReturnType<Timeline['snapshot']>|undefined} saved */
  restore(saved) {
    this.pause();
    if (!saved || !Array.isArray(saved.keys)) return;
    this.durationMs = saved.durationMs ?? this.durationMs;
    this.fps = saved.fps ?? this.fps;
    this.timeMs = Math.min(saved.timeMs ?? 0, this.durationMs);
    this.keys = saved.keys;
    this._nextId = Math.max(this._nextId, ...this.keys.map((k) => (k.id ?? 0) + 1));
    this.pivots = saved.pivots;
    if (saved.base) this.rebase(saved.base, saved.base.length);
    this._giveShapesBack();
    this._changed();
  }

  // ------------------------------------------------------------------ time

  setDuration(/** @type {number} */ seconds) {
    if (!Number.isFinite(seconds) || seconds <= 0) return this.render();
    const last = this.keys.length ? this.keys[this.keys.length - 1].ms : 0;
    this.durationMs = Math.max(Math.round(seconds * 1000), last, 1);
    this.timeMs = Math.min(this.timeMs, this.durationMs);
    this._changed();
    return undefined;
  }

  setFps(/** @type {number} */ fps) {
    if (Number.isFinite(fps) && fps >= 1 && fps <= 120) this.fps = fps;
    this._changed();
  }

  /** The interpolated transforms of every server group at `ms`, or null.
   * @param {number} ms */
  transformsAt(ms) {
    if (!this.keys.length || this.deps.blocked()) return null;
    if (this.deps.transforms().length !== this.keys[0].transforms.length) return null;
    return interpolate(this.keys, this.pivots || [], ms / 1000);
  }

  /** Move the playhead to `ms`; with keyframes, the handles go to their pose there (a drag; at a keyframe, one that
   * names it, so that the server shows the shape it kept). @param {number} ms */
  seek(ms) {
    this.timeMs = Math.max(0, Math.min(Math.round(ms), this.durationMs));
    const t = this.transformsAt(this.timeMs);
    if (t) {
      this.deps.drag(t, this.current()?.id);
      this.dragsSent++;
      this._moved = true;
    }
    this.render();
    return !!t;
  }

  /** The drags since the last one end as an undo step (the server then settles the shape). */
  _endMove() {
    if (!this._moved) return;
    this._moved = false;
    this.deps.endDrag();
  }

  play() {
    if (this.playing) return;
    if (this.keys.length < 2) return this.deps.say('Add two keyframes at different times to play.', 'info');
    const why = this.deps.blocked();
    if (why) return this.deps.say(`Cannot play: ${why}.`, 'error');
    this.playing = true;
    this._frame = -1;
    const loop = Math.floor((this.durationMs / 1000) * this.fps + 1e-9) + 1; // frames of one pass
    const startFrame = Math.round((this.timeMs / 1000) * this.fps) % loop;
    const start = performance.now() - (startFrame / this.fps) * 1000;
    const tick = (/** @type {number} */ now) => {
      if (!this.playing) return;
      if (this.deps.blocked()) {
        this.pause(); // a drag of the gizmo, a new selection, the connection lost
        return;
      }
      const frame = Math.floor(((now - start) / 1000) * this.fps) % loop;
      if (frame !== this._frame) {
        this._frame = frame;
        if (this.seek((frame / this.fps) * 1000)) this.framesShown++;
      }
      this._raf = requestAnimationFrame(tick);
    };
    this._raf = requestAnimationFrame(tick);
    this.render();
    return undefined;
  }

  pause() {
    if (!this.playing) return;
    this.playing = false;
    cancelAnimationFrame(this._raf);
    this._endMove();
    this.render();
  }

  // ------------------------------------------------------------------ pointer on the bar

  /** The time under the pointer: within a pixel of either end of the bar, that end (the last pixel column of the
   * bar is 1 px short of its width, so a click there would miss the end by one pixel's time). */
  _msAt(/** @type {PointerEvent} */ e) {
    const r = this.bar.getBoundingClientRect();
    const x = Math.max(0, Math.min(e.clientX - r.left, r.width));
    if (x >= r.width - 1.5) return this.durationMs;
    if (x <= 1) return 0;
    return (x / Math.max(r.width, 1)) * this.durationMs;
  }

  _pointerDown(/** @type {PointerEvent} */ e) {
    if (e.button !== 0 || /** @type {any} */ (this.bar).disabled) return;
    this.pause();
    this.scrubbing = true;
    this.bar.setPointerCapture(e.pointerId);
    const marker = /** @type {HTMLElement} */ (e.target).closest?.('.tl-marker');
    if (marker) {
      // a click goes to the keyframe; moving off the marker with the button held scrubs from there
      this._pressX = e.clientX;
      this.seek(Number(/** @type {HTMLElement} */ (marker).dataset.ms));
      return;
    }
    this._pressX = null;
    this.seek(this._msAt(e));
  }

  _pointerMove(/** @type {PointerEvent} */ e) {
    if (!this.scrubbing) return;
    if (this._pressX !== null && Math.abs(e.clientX - this._pressX) < 4) return; // still on the marker
    this._pressX = null;
    this.seek(this._msAt(e));
  }

  _pointerUp(/** @type {PointerEvent} */ e) {
    if (!this.scrubbing) return;
    this.scrubbing = false;
    this._pressX = null;
    if (this.bar.hasPointerCapture(e.pointerId)) this.bar.releasePointerCapture(e.pointerId);
    this._endMove();
  }

  /** Go to a time (a keyframe's): one drag there, ending at once. @param {number} ms */
  goTo(ms) {
    this.pause();
    this.seek(ms);
    this._endMove();
  }

  // ------------------------------------------------------------------ documents and export

  /**
   * Fields of get_constraints / export_animation for the keyframes, or null without any (or when stale).
   * @returns {{times_ms: number[], transforms: number[][], easings: number[], keys: number[]}|null}
   */
  messageFields() {
    if (!this.keys.length || this.keys[0].transforms.length !== this.deps.transforms().length) return null;
    return {
      times_ms: this.keys.map((k) => k.ms),
      transforms: this.keys.flatMap((k) => k.transforms),
      easings: this.keys.map((k) => Math.max(EASINGS.indexOf(k.easing ?? 'linear'), 0)),
      keys: this.keys.map((k) => k.id ?? 0),
    };
  }

  exportAnimation() {
    if (this.keys.length < 2) return this.deps.say('Add two keyframes at different times to export an animation.', 'info');
    const why = this.deps.blocked();
    if (why) return this.deps.say(`Cannot export the animation: ${why}.`, 'error');
    const frames = frameCount(this.keys, this.fps);
    if (frames > MAX_EXPORT_FRAMES) {
      return this.deps.say(`${frames} frames at ${this.fps} fps: an export holds at most ${MAX_EXPORT_FRAMES}; lower `
        + 'the frame rate or bring the keyframes closer.', 'error');
    }
    this.pause();
    const fields = this.messageFields();
    if (!fields) return undefined;
    /** @type {ExportAnimationClientMessage} */
    const msg = { type: CLIENT.EXPORT_ANIMATION, fps: this.fps, format: this.format, ...fields };
    if (!this.deps.send(msg)) return undefined;
    this.exporting = true;
    this.exportNote = `Solving ${frames} frames…`;
    this.render();
    return undefined;
  }

  /**
   * A server message: export progress and result; true when it was one of those.
   * @param {ServerMessage & {frame?: {payload: Uint8Array}}} msg a binary one with its frame
   */
  received(msg) {
    if (msg.type === SERVER.ANIMATION_PROGRESS) {
      if (msg.status === 'cancelled') {
        this.exporting = false;
        this.exportNote = 'Export cancelled.';
      } else {
        this.exportNote = `Solving frame ${msg.frame} of ${msg.frames}…`;
      }
      this.render();
      return true;
    }
    if (msg.type === SERVER.ANIMATION) {
      this.exporting = false;
      this.exportNote = `${msg.frames} frames in ${msg.seconds.toFixed(1)} s.`;
      const bytes = msg.frame ? msg.frame.payload.byteLength : 0; // an animation message always has its frame
      this.lastExport = { frames: msg.frames, seconds: msg.seconds, bytes };
      this.deps.say(this.deps.download(msg), 'info');
      this.render();
      return true;
    }
    return false;
  }

  /** An error answered the export. @param {string} message */
  failed(message) {
    this.exporting = false;
    this.exportNote = `Export failed: ${message}`;
    this.render();
  }

  // ------------------------------------------------------------------ view

  _changed() {
    this.render();
    this.deps.changed();
  }

  render() {
    const pct = (/** @type {number} */ ms) => `${(100 * ms) / Math.max(this.durationMs, 1)}%`;
    this.playhead.style.left = pct(this.timeMs);
    this.markers.replaceChildren(...this.keys.map((k, i) => {
      const m = document.createElement('div');
      m.className = `tl-marker${k.ms === this.timeMs ? ' current' : ''}`;
      m.dataset.ms = String(k.ms);
      m.dataset.testid = 'tl-marker';
      m.title = `Keyframe ${i + 1} at ${(k.ms / 1000).toFixed(3)} s: click to go to it`;
      m.style.left = pct(k.ms);
      return m;
    }));
    byId('tl-time').textContent = `${(this.timeMs / 1000).toFixed(3)} s`;
    const key = this.current();
    const at = byIdAs('tl-time-input', HTMLInputElement);
    const keyTime = byIdAs('tl-key-time', HTMLInputElement);
    const easing = byIdAs('tl-easing', HTMLSelectElement);
    if (document.activeElement !== at) at.value = String(this.timeMs / 1000);
    keyTime.disabled = !key;
    easing.disabled = !key;
    if (document.activeElement !== keyTime) keyTime.value = key ? String(key.ms / 1000) : '';
    easing.value = key?.easing ?? 'linear';
    byIdAs('tl-format', HTMLSelectElement).value = this.format ?? 'glb';
    const n = this.keys.length;
    byId('tl-count').textContent = n ? `${n} keyframe${n > 1 ? 's' : ''}` : 'no keyframes';
    byId('btn-tl-play').textContent = this.playing ? 'Pause' : 'Play';
    byId('btn-tl-play').classList.toggle('active', this.playing);
    byId('tl-progress').textContent = this.exportNote;
    const duration = byIdAs('tl-duration', HTMLInputElement);
    const fps = byIdAs('tl-fps', HTMLInputElement);
    if (document.activeElement !== duration) duration.value = String(this.durationMs / 1000);
    if (document.activeElement !== fps) fps.value = String(this.fps);
  }
}
