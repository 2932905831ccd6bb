// Loading a mesh into the session: a built-in model by name, a mesh file the user chose or dropped (checked
// against the server's upload limit first), or a saved session's source; each asks before throwing edits away
// (SessionKeeper.confirmReplace) and records the steps of an upload's timing.
import { bundleFiles, checkMeshFile } from './files.js';
import { CLIENT, SERVER } from './protocol.js';
import { builtinSource, fileSource } from './snapshot.js';

/** @typedef {import('./stores/meshstore.js').MeshSource} MeshSource */

/**
 * What loading reads and tells.
 * @typedef {object} MeshLoadingDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/diagnostics.js').Diagnostics} diagnostics
 * @property {import('./connection.js').Connection} conn
 * @property {import('./keeper.js').SessionKeeper} keeper
 * @property {import('./panel.js').Panel} panel
 * @property {() => void} notConnected say that nothing can be sent
 * @property {(text: string|null, forType?: string) => void} setBusy
 */

export class MeshLoading {
  /** @param {MeshLoadingDeps} deps */
  constructor(deps) {
    this.d = deps;
  }

  /**
   * Load a mesh source (snapshot.js): a built-in model by name, or a mesh file's bytes. False when not connected.
   * @param {MeshSource} source
   */
  request(source) {
    const { d } = this;
    const ok = source.kind === 'builtin'
      ? d.conn.send({ type: CLIENT.LOAD_BUILTIN, name: /** @type {string} */ (source.name) })
      : d.conn.sendBinary({ type: CLIENT.UPLOAD, filename: /** @type {string} */ (source.filename) }, source.bytes);
    if (!ok) {
      d.notConnected();
      return false;
    }
    if (source.kind !== 'builtin') d.diagnostics.mark('sent');
    d.keeper.meshRequested(source);
    d.setBusy(`Loading ${source.kind === 'builtin' ? source.name : source.filename}…`, SERVER.MESH);
    return true;
  }

  /**
   * Upload a mesh file the user chose, or several chosen or dropped together: a mesh file with the MTL files,
   * textures and buffers it names, sent as one zip (files.js bundleFiles).
   * @param {File|File[]} chosen
   */
  upload(chosen) {
    const { d } = this;
    if (!Array.isArray(chosen) || chosen.length === 1) {
      this.uploadOne(Array.isArray(chosen) ? chosen[0] : chosen);
      return;
    }
    bundleFiles(chosen).then((file) => this.uploadOne(file), (/** @type {Error} */ err) => {
      d.diagnostics.error('client_check', err.message, CLIENT.UPLOAD);
      d.panel.showStatus(err.message, 'error');
    });
  }

  /**
   * Upload one file.
   * @param {File} file
   */
  uploadOne(file) {
    const { d } = this;
    const problem = checkMeshFile(file, d.mesh.limits.max_upload_bytes);
    if (problem) {
      d.diagnostics.error('client_check', problem, CLIENT.UPLOAD);
      d.panel.showStatus(problem, 'error');
      return;
    }
    if (!d.keeper.confirmReplace(file.name)) return;
    d.diagnostics.uploadChosen();
    file.arrayBuffer().then((buf) => {
      d.diagnostics.mark('read');
      this.request(fileSource(file.name, buf));
    });
  }

  /**
   * Load the built-in model `name` (the panel's model list); the list goes back when the user keeps the mesh shown.
   * @param {string} name
   */
  builtin(name) {
    const { d } = this;
    if (!name || (name === d.mesh.name && d.mesh.builtin)) return;
    if (d.keeper.confirmReplace(name)) this.request(builtinSource(name));
    else d.panel.setCurrentModel(d.mesh.name, d.mesh.builtin);
  }
}
