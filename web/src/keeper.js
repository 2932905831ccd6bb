// Keeps the studio's work safe: asks before edits are thrown away, autosaves the session, offers a saved session
// after a reload or a crash, and puts the session back by itself after the connection to the server was lost.
import { Autosave, warnBeforeUnload } from './autosave.js';
import { showRestoreOffer } from './offer.js';
import { CLIENT } from './protocol.js';
import { SessionRestore } from './restore.js';
import { deleteSession, getMesh, newestOrphan, newSessionId } from './sessiondb.js';
import {
  builtinSource, captureSession, describe, encodePly, fileSource, hasEdits, isPictureSource, pictureSource, restExportFormat,
} from './snapshot.js';

/**
 * What the keeper reads and tells.
 * @typedef {object} KeeperDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/historystore.js').HistoryStore} history
 * @property {import('./stores/paramstore.js').ParamStore} params
 * @property {import('./selection.js').Selection} selection
 * @property {import('./viewer.js').Viewer} viewer
 * @property {import('./panel.js').Panel} panel
 * @property {import('./gizmo.js').HandleGizmo} gizmo
 * @property {(msg: import('./protocol.js').ClientMessage) => boolean} send
 * @property {(source: import('./stores/meshstore.js').MeshSource) => boolean} requestMesh load or upload it
 * @property {(snap: any) => void} applySelection put a saved selection back and send it
 * @property {HTMLElement} offerParent the element of the restore offer's banner
 */

export class SessionKeeper {
  /** @param {KeeperDeps} deps */
  constructor(deps) {
    this.deps = deps;
    this.id = newSessionId();
    this.pendingSource = null; // source of the mesh requested last
    this.madeSource = false; // the mesh shown came from the server (its own file): its source is a PLY made here
    this.picture = false; // the mesh shown is a picture's
    /** @type {string[]} the densities of the remesh requests whose mesh has not arrived yet, in order */
    this.remeshes = [];
    this.applying = 0; // apply requests whose state has not arrived yet
    /**
     * Per export request not answered yet, in order: false for a download, else the rest pose kept as the mesh's
     * source, a file named after the mesh (`name`), so that a restore shows the same name.
     * @type {(false|{name: string})[]}
     */
    this.exports = [];
    /** @type {false|{name: string}} what the export being sent is for */
    this.exportingRest = false;
    this.lost = null; // {snap, live}: the session when the connection was lost, put back after reconnecting
    this.queued = null; // {snap, recordId}: a restore chosen before the session was ready
    this.rest = null; // the rest pose of the mesh shown (as loaded, or as the last apply made it)
    this.offer = null; // {banner, record}: the restore offer shown
    let failed = false;
    this.autosave = new Autosave({
      id: this.id,
      capture: () => captureSession(this._session(), this.rest),
      delayMs: () => 500 + deps.viewer.nVertices / 200, // large meshes are written less often
      onError: (err) => {
        if (!failed) deps.panel.showStatus(`Autosave failed: ${err.message || err}`, 'error');
        failed = true;
      },
    });
    this.restore = new SessionRestore({ send: deps.send, requestMesh: deps.requestMesh, applySelection: deps.applySelection });
    warnBeforeUnload(() => this.hasEdits());
  }

  hasEdits() {
    return hasEdits(this._session());
  }

  /** The session as snapshot.js reads it: the stores' fields under the names of a saved session. */
  _session() {
    const { mesh, history, params, selection, viewer } = this.deps;
    /** @type {import('./snapshot.js').SessionFacts} */
    const facts = {
      canUndo: history.canUndo,
      canRedo: history.canRedo,
      source: mesh.source,
      meshName: mesh.name,
      nFaces: mesh.nFaces,
      params: params.values,
    };
    return { facts, selection, viewer, gizmo: this.deps.gizmo };
  }

  /** Work of this page waits for the server: a session to put back after reconnecting, or a chosen restore. */
  get keepsWork() {
    return !!(this.lost?.snap?.edits || this.queued);
  }

  /**
   * True when the current session may be replaced: it has no edits, or the user agrees to lose them.
   * @param {string} what what replaces it, in words
   */
  confirmReplace(what) {
    if (!this.hasEdits()) return true;
    return window.confirm(`Replace ${this.deps.mesh.name || 'the current mesh'} with ${what}? Its selection, ` +
      'handle groups, deformation and undo history will be lost.');
  }

  /** Something in the session changed. */
  touch() {
    this.autosave.touch();
  }

  /**
   * A mesh source (snapshot.js) was requested.
   * @param {import('./stores/meshstore.js').MeshSource} source
   */
  meshRequested(source) {
    this.pendingSource = source;
    this.madeSource = false;
  }

  /** @param {import('./protocol.js').ClientMessage} msg a message sent to the server */
  sent(msg) {
    if (msg.type === CLIENT.EXPORT) this.exports.push(this.exportingRest);
    if (msg.type === CLIENT.REMESH) this.remeshes.push(msg.density);
    if (msg.type !== CLIENT.APPLY) return;
    this.applying++;
    // a mesh with a look (UVs, textures, colours) keeps it through a restore: the rest pose is kept as a file of the
    // source's kind, exported now (before anything can move the shape away from the new rest pose)
    const format = this.deps.viewer.look ? restExportFormat(this.deps.mesh.source) : null;
    if (format) this._exportRest(format, this.deps.mesh.name ?? 'model');
  }

  /**
   * Ask for the shape shown as a file of `format`, kept as the mesh's source instead of downloaded.
   * @param {'glb'|'ply'|'obj'} format
   * @param {string} name the source's file name without its extension
   */
  _exportRest(format, name) {
    this.exportingRest = { name };
    try {
      this.deps.send({ type: CLIENT.EXPORT, format });
    } finally {
      this.exportingRest = false;
    }
  }

  /**
   * The look of the mesh just sent arrived (`fileFormat`: its file's format; `texture`: its image). A mesh the server
   * opened itself (the one it was started with) has only a PLY of its triangles as its source here, which would lose
   * the look in a restore; its file is asked for now, while the shape is its rest pose, and kept as the source. A
   * picture's file is the picture itself, which its look brings as its texture (the picture's pixels, as PNG): kept
   * as the source, a restore opens it again as a picture, meshed the same.
   * @param {string} fileFormat
   * @param {Blob|null} [texture]
   */
  appearanceArrived(fileFormat, texture = null) {
    if (!this.madeSource) return;
    this.madeSource = false;
    if (this.picture) {
      if (texture) this._keepPicture(texture);
      return;
    }
    const format = restExportFormat({ kind: 'file', filename: `mesh.${fileFormat}` });
    if (format) this._exportRest(format, this.deps.mesh.name ?? 'model');
  }

  /**
   * Keep a picture's image as the source of the mesh shown, in place of the PLY of its triangles (unless another
   * mesh or source came meanwhile, or it is over the upload limit).
   * @param {Blob} texture
   */
  _keepPicture(texture) {
    const { mesh } = this.deps;
    const made = mesh.source;
    const ext = texture.type === 'image/jpeg' ? 'jpg' : 'png';
    texture.arrayBuffer().then((bytes) => {
      if (mesh.source !== made) return;
      if (mesh.limits.max_upload_bytes && bytes.byteLength > mesh.limits.max_upload_bytes) return;
      mesh.sourceKnown(fileSource(`${mesh.name ?? 'picture'}.${ext}`, bytes));
      this.touch();
    }, () => {});
  }

  /**
   * An export arrived: true when it is the rest pose asked for after an apply, kept as the mesh's source (what a
   * restore uploads) instead of being downloaded.
   * @param {import('./protocol.js').ExportServerMessage & import('./messages.js').Framed} msg
   */
  exportArrived(msg) {
    const rest = this.exports.shift();
    if (!rest) return false;
    const { mesh } = this.deps;
    const bytes = msg.frame.payload.slice();
    const filename = `${rest.name}.${msg.filename.split('.').pop()}`;
    if (!mesh.limits.max_upload_bytes || bytes.byteLength <= mesh.limits.max_upload_bytes) {
      mesh.sourceKnown(fileSource(filename, bytes, mesh.repaired));
      this.touch();
    }
    return true;
  }

  /** The open connection was lost: keep the session to put it back once reconnected. */
  connectionLost() {
    this.pendingSource = null;
    this.madeSource = false;
    this.applying = 0;
    this.exports = [];
    this.remeshes = [];
    const restoring = this.restore.cancel();
    if (restoring) this.lost = { snap: restoring, live: false };
    else if (!this.lost && !this.autosave.held) this.lost = { snap: this.autosave.hold(), live: true };
  }

  /** The server greeted a new connection (its mesh follows). */
  welcomed() {
    // the selection may have been edited while disconnected: take it as it is now
    if (this.lost?.live) this.lost.snap = captureSession(this._session(), this.rest);
  }

  /**
   * A mesh arrived (positions and faces as sent).
   * @param {import('./protocol.js').MeshServerMessage} msg
   * @param {Float32Array} positions
   * @param {Uint32Array} faces
   */
  meshArrived(msg, positions, faces) {
    const { mesh } = this.deps;
    this.picture = !!msg.picture;
    // a picture meshed again at another density: its picture stays the source, with the density to mesh it at
    const density = this.picture ? this.remeshes.shift() : undefined;
    const builtin = !!msg.builtin; // not the name: a file may be named like a built-in model
    this.madeSource = !this.pendingSource && !builtin && density === undefined;
    const picture = density !== undefined && isPictureSource(mesh.source) ? mesh.source : null;
    mesh.sourceKnown(this.pendingSource ?? (builtin ? builtinSource(msg.name)
      : picture ? pictureSource(picture, /** @type {string} */ (density))
        : fileSource(`${msg.name}.ply`, encodePly(positions, faces, mesh.vertexMap), mesh.repaired)));
    this.pendingSource = null;
    this.rest = Float32Array.from(positions);
    if (this.offer?.banner.open) this.offer.banner.setText(describe(this.offer.record, msg.name));
    if (this.restore.meshArrived(msg, positions)) return;
    if (this.lost) {
      const { snap } = this.lost;
      this.lost = null;
      if (snap.edits) this.startRestore(snap, null);
      else this.autosave.resume();
    } else if (this.queued) {
      const { snap, recordId } = this.queued;
      this.queued = null;
      this.startRestore(snap, recordId);
    }
  }

  /**
   * A state arrived; `synced`: the server holds the local selection.
   * @param {boolean} synced
   */
  stateArrived(synced) {
    const { mesh, viewer } = this.deps;
    if (this.applying > 0) {
      // the deformed shape is now the rest pose: a restore must upload it (as a PLY until the export of a mesh
      // with a look arrives, exportArrived); a picture stays its source, which a PLY would lose (a restore opens the
      // picture and puts the shape back on it)
      this.applying--;
      this.rest = Float32Array.from(viewer.positions);
      if (isPictureSource(mesh.source)) {
        this.restore.stateArrived(synced);
        return;
      }
      // an apply was answered, so a mesh is shown: its geometry and triangles are there
      const geometry = /** @type {NonNullable<typeof viewer.geometry>} */ (viewer.geometry);
      const faces = /** @type {import('three').BufferAttribute} */ (geometry.index).array;
      const bytes = encodePly(viewer.positions, faces, mesh.vertexMap);
      if (!mesh.limits.max_upload_bytes || bytes.byteLength <= mesh.limits.max_upload_bytes) {
        mesh.sourceKnown(fileSource(`${mesh.name}.ply`, bytes, mesh.repaired));
      }
    }
    this.restore.stateArrived(synced);
  }

  /** @param {import('./protocol.js').ErrorServerMessage} msg */
  errorArrived(msg) {
    if (msg.request === CLIENT.LOAD_BUILTIN || msg.request === CLIENT.UPLOAD) this.pendingSource = null;
    if (msg.request === CLIENT.APPLY) this.applying = Math.max(0, this.applying - 1);
    if (msg.request === CLIENT.REMESH) this.remeshes.shift();
    if (msg.request === CLIENT.EXPORT) this.exports.shift();
    this.restore.errorArrived(msg);
  }

  /**
   * Put a saved session back (`recordId`: its saved record, deleted once restored).
   * @param {import('./autosave.js').Snapshot} snap
   * @param {string|null} recordId
   */
  startRestore(snap, recordId) {
    const { mesh, panel } = this.deps;
    this.madeSource = false; // the restore replaces the mesh shown (and its shape): not the file's rest pose
    if (!mesh.ready) {
      this.queued = { snap, recordId };
      panel.showStatus('The saved session is restored as soon as the studio server answers.', 'info');
      return;
    }
    if (!this.autosave.held) this.autosave.hold();
    panel.showStatus(`Restoring ${snap.meshName}…`, 'info');
    this.restore.start(snap, (/** @type {string|null} */ error) => {
      if (error && !recordId) {
        // keep what was saved of this page's session (offered after a reload) and save on under a new id
        this.id = newSessionId();
        this.autosave.renew(this.id);
      }
      this.autosave.resume();
      if (error) {
        panel.showStatus(`Could not restore the saved session: ${error}.`, 'error');
        return;
      }
      if (recordId && recordId !== this.id) deleteSession(recordId).catch(() => {});
      panel.showStatus(`Restored ${snap.meshName}.`, 'info', 4000);
    });
  }

  /** Offer the newest saved session of a page that is gone (a reload, a crash, a closed tab). */
  async offerSaved() {
    const record = await newestOrphan(this.id);
    if (!record || !record.edits) return;
    const banner = showRestoreOffer(this.deps.offerParent, {
      text: describe(record, this.deps.mesh.name),
      onRestore: () => {
        if (!this.confirmReplace(`the saved ${record.meshName}`)) return false;
        this._restoreRecord(record).catch((err) => this.deps.panel.showStatus(`Could not restore: ${err.message || err}`, 'error'));
        return true;
      },
      onDiscard: () => deleteSession(record.id).catch(() => {}),
    });
    this.offer = { banner, record };
  }

  /** @param {import('./sessiondb.js').SavedSession} record */
  async _restoreRecord(record) {
    let source = record.source;
    if (source.kind === 'file') {
      const mesh = await getMesh(record.id);
      if (!mesh || mesh.key !== source.key) {
        this.deps.panel.showStatus('Could not restore the saved session: its mesh is missing.', 'error');
        return;
      }
      source = { ...source, bytes: mesh.bytes };
    }
    this.startRestore({ ...record, source }, record.id);
  }
}
