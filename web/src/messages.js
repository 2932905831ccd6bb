// What the page does with each message of the studio server: the welcome (protocol version, limits, built-in
// models), a new mesh (everything that refers to the old one starts over), its appearance, vertices frames (drawn
// at the page's frame rate by LivePose), the session's state (history, parameters and, through ConstraintSync, the
// constraint set), settling progress, documents and exports to download, and errors. The stores take what the
// messages say; this module tells the views.
import { downloadConstraints, downloadExport } from './files.js';
import { meshArrays } from './frames.js';
import { pinsStated } from './picturemode.js';
import { CLIENT, ERROR, PROTOCOL_VERSION, SERVER } from './protocol.js';
import { appearanceArrays } from './texture.js';

/** @typedef {import('./protocol.js').ServerMessage} ServerMessage */
/** @typedef {import('./protocol.js').WelcomeServerMessage} WelcomeServerMessage */
/** @typedef {import('./protocol.js').MeshServerMessage} MeshServerMessage */
/** @typedef {import('./protocol.js').AppearanceServerMessage} AppearanceServerMessage */
/** @typedef {import('./protocol.js').VerticesServerMessage} VerticesServerMessage */
/** @typedef {import('./protocol.js').StateServerMessage} StateServerMessage */
/** @typedef {import('./protocol.js').ErrorServerMessage} ErrorServerMessage */
/** A binary message's header fields with its `frame` (connection.js). @typedef {{frame?: any}} Framed */
/** @typedef {{frame: {header: any, payload: Uint8Array}}} WithFrame a message that is always binary */

/**
 * Why point handles are not saved for a mesh that repair changed (the server says the same of a mesh it repaired
 * itself; a session restored from the PLY of such a mesh is one it did not repair).
 * @param {string|null} name
 */
export const POINTS_NOT_SAVED = (name) => `Point handles cannot be saved in a constraints document for ${name}: they `
  + 'refer to the triangles of the mesh as repaired when it was loaded, not to the file\'s, and arap deform refuses '
  + 'point handles on a mesh that repair changes; remove the point handles, or repair the mesh file first (arap info '
  + 'shows what repair changes).';

/**
 * What the message handling reads and tells.
 * @typedef {object} MessageDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/historystore.js').HistoryStore} history
 * @property {import('./stores/paramstore.js').ParamStore} params
 * @property {import('./stores/diagnostics.js').Diagnostics} diagnostics
 * @property {import('./constraintsync.js').ConstraintSync} sync
 * @property {import('./viewer.js').Viewer} viewer
 * @property {import('./livepose.js').LivePose} livePose
 * @property {import('./selection.js').Selection} selection
 * @property {import('./gizmo.js').HandleGizmo} gizmo
 * @property {ReturnType<typeof import('./transformui.js').installTransformUi>} transformUi
 * @property {import('./timeline.js').Timeline} timeline
 * @property {import('./stats.js').UpdateStats} stats
 * @property {import('./panel.js').Panel} panel
 * @property {import('./heatmap.js').HeatMap} heat
 * @property {import('./mirror.js').MirrorEditing} mirror
 * @property {import('./keeper.js').SessionKeeper} keeper
 * @property {import('./help.js').Help} help
 * @property {import('./pointhandles.js').PointHandles} points
 * @property {import('./connection.js').Connection} conn
 * @property {(full?: boolean) => void} refreshSelection redraw the selection (full: its panel list at once)
 * @property {() => void} updateGroupsUi
 * @property {(text: string|null, forType?: string) => void} setBusy
 * @property {(text: string) => void} showRequestError
 * @property {() => void} commitConstraints send the selection when the server does not hold it
 */

export class ServerMessages {
  /** @param {MessageDeps} deps */
  constructor(deps) {
    this.d = deps;
  }

  /**
   * A message of the server (a binary one as its header fields plus its `frame`).
   * @param {ServerMessage & Framed} msg
   */
  handle(msg) {
    const { d } = this;
    d.diagnostics.messageReceived();
    if (msg.type !== SERVER.WELCOME && d.mesh.incompatible) return undefined;
    d.keeper.touch();
    // a shape received and not drawn yet is shown before anything that may read it; settling progress is not such
    if (msg.type === SERVER.MESH) d.livePose.reset();
    else if (msg.type !== SERVER.VERTICES && !(msg.type === SERVER.SETTLE && msg.status === 'settling')) {
      d.livePose.flush();
    }
    switch (msg.type) {
      case SERVER.WELCOME:
        return this.welcome(msg);
      case SERVER.MESH:
        return this.meshArrived(msg);
      case SERVER.APPEARANCE:
        return this.appearance(msg);
      case SERVER.VERTICES:
        return this.vertices(msg);
      case SERVER.STATE:
        return this.state(msg);
      case SERVER.SETTLE:
        if (Number.isFinite(msg.energy)) d.stats.noteEnergies([/** @type {number} finite */ (msg.energy)]);
        if (msg.status !== 'settling') d.timeline.settled();
        return d.panel.setSettle(msg);
      case SERVER.CONSTRAINTS: // the document carries the mirror pairs of its handle groups in "meta"
        if (d.mesh.repaired && msg.document?.points?.length) {
          return d.showRequestError(POINTS_NOT_SAVED(d.mesh.name));
        }
        return d.panel.showStatus(downloadConstraints(d.mirror.documentWithPartners(msg.document, d.sync.groupMap),
          d.mesh.name), 'info', 2500);
      case SERVER.EXPORT:
        if (d.keeper.exportArrived(msg)) return undefined; // the rest pose an apply made, kept for a restore
        return d.panel.showStatus(downloadExport(msg), 'info', 3000);
      case SERVER.ANIMATION_PROGRESS:
      case SERVER.ANIMATION:
        return d.timeline.received(msg);
      case SERVER.DISTORTION:
        return d.heat.received(/** @type {typeof msg & WithFrame} */ (msg)); // a binary message
      case SERVER.PREPARING: // first run: the kernels compile before the welcome
        return d.panel.preparingSolver(msg);
      case SERVER.ERROR:
        return this.error(msg);
      default:
        return undefined;
    }
  }

  /** @param {WelcomeServerMessage} msg */
  welcome(msg) {
    const { d } = this;
    if (!d.mesh.welcomed(msg, PROTOCOL_VERSION)) {
      // a page left open across an upgrade of the server: its messages would be misread
      d.panel.protocolMismatch(PROTOCOL_VERSION, msg.protocol);
      return;
    }
    d.keeper.welcomed();
    d.panel.setBuiltins(d.mesh.builtins, d.mesh.name, d.mesh.builtin);
    d.panel.setParams(msg.params);
    d.params.take(msg.params);
    d.setBusy('Loading mesh…', SERVER.MESH);
  }

  /** @param {MeshServerMessage & Framed} msg */
  meshArrived(msg) {
    const { d } = this;
    const t0 = performance.now();
    d.diagnostics.mark('received', performance.timeOrigin + t0);
    const { positions, faces, vertexMap } = meshArrays(msg.frame);
    d.viewer.setMesh(positions, faces);
    showLoadNote(null, []); // an appearance right after says what this mesh's file could not show
    d.panel.setSurfaces(d.viewer.surfaces, d.viewer.surface); // plain until an appearance says otherwise
    d.livePose.reset();
    d.selection.reset(msg.n_vertices);
    d.gizmo.syncGroups(1);
    d.gizmo.resetTransforms();
    d.transformUi.meshChanged();
    d.mesh.shown(msg, vertexMap);
    d.timeline.clear();
    d.sync.meshLoaded();
    d.mesh.setUp();
    d.stats.reset();
    d.panel.meshLoaded(msg);
    d.refreshSelection(true);
    d.heat.meshChanged();
    d.setBusy(null);
    d.mirror.meshChanged(positions, faces); // after the status line: it may say that no symmetry was found
    d.keeper.meshArrived(msg, positions, faces);
    d.mesh.sourceArrived();
    d.diagnostics.meshShown(performance.now() - t0);
    d.diagnostics.mark('shown');
    requestAnimationFrame(() => d.diagnostics.mark('drawn')); // after the viewer's own frame callback: drawn once
  }

  /**
   * The mesh file's look, right after its mesh: its texture on a render mesh or its vertex colours, and the panel's
   * surface choice; notes say what is not shown.
   * @param {AppearanceServerMessage & Framed} msg
   */
  appearance(msg) {
    const { d } = this;
    const look = appearanceArrays(msg.frame, d.viewer.nVertices);
    d.viewer.setLook(look);
    d.keeper.appearanceArrived(msg.file_format, look.texture);
    d.panel.setSurfaces(d.viewer.surfaces, d.viewer.surface);
    d.refreshSelection(false);
    if (msg.notes?.length) d.panel.showStatus(`${d.mesh.name}: ${msg.notes.join('; ')}.`, 'info', 10000);
    showLoadNote(d.mesh.name, msg.notes || []);
  }

  /**
   * A vertices frame: kept until the next animation frame, when the newest one received is drawn.
   * @param {VerticesServerMessage & Framed} msg
   */
  vertices(msg) {
    if (this.d.livePose.receive(msg.frame, msg) && msg.iterations > 0) this.d.stats.received(msg);
  }

  /**
   * The newest shape received was applied (livePose): what depends on it follows. `w.seq` is the newest request it
   * answers (-1: only frames the server sent on its own, settling or undo).
   * @param {import('./livepose.js').Waiting} w
   * @param {number} ms
   */
  shapeApplied(w, ms) {
    const { d } = this;
    d.diagnostics.frameApplied(ms);
    d.heat.shapeChanged();
    if (w.seq >= 0) d.mesh.dragAnswered(w.seq);
    d.gizmo.recenter();
    d.points.refresh();
    if (w.solved) d.stats.frame(w.solved); // not for a pose change without a solve (undo, reset)
  }

  /** @param {StateServerMessage} msg */
  state(msg) {
    const { d } = this;
    pinsStated(msg, d.viewer);
    if (d.history.stateArrived(msg)) d.help.guideProgress({ drag: true }); // the state that answers a drag's end
    d.mirror.stateArrived(msg.rest_id);
    d.panel.setHistory(d.history.canUndo, d.history.canRedo);
    d.panel.setParams(msg.params);
    d.params.take(msg.params);
    if (msg.stats) d.panel.setStats(msg.stats);
    const outcome = d.sync.stateArrived(msg, (key) => d.keeper.restore.isPinStep(key) && this.stepOverPin(msg));
    if (outcome === 'stepped') return;
    if (!d.gizmo.dragging) d.gizmo.setTransforms(msg.transforms, d.sync.groupMap);
    if (d.history.busyFor === SERVER.STATE) d.setBusy(null);
    d.updateGroupsUi();
    d.keeper.stateArrived(!d.sync.pending);
  }

  /**
   * Undo or redo reached the constraint set with which a restore put the saved shape back (every moved vertex a
   * handle): not a state the user made, so go on in the same direction (the other one when that is not possible).
   * False when neither is possible (the state is then shown as it is).
   * @param {StateServerMessage} msg
   */
  stepOverPin(msg) {
    const type = this.d.history.stepOver(msg);
    if (type === null) return false;
    return this.d.conn.send({ type }); // lastHistory stays: a further step over it goes the way the user went
  }

  /** @param {ErrorServerMessage} msg */
  error(msg) {
    const { d } = this;
    d.diagnostics.error(msg.code, msg.message, msg.request ?? null);
    d.sync.errorArrived(msg);
    if (msg.request === CLIENT.SET_PARAMS) d.panel.setParams(d.params.values); // the controls show what the server uses
    if (d.history.busyFor) d.setBusy(null);
    if (msg.request === CLIENT.END_DRAG) d.history.endDragRefused();
    if (msg.request === CLIENT.GET_DISTORTION) d.heat.failed();
    if (msg.request === CLIENT.EXPORT_ANIMATION) d.timeline.failed(msg.message || msg.code);
    d.keeper.errorArrived(msg);
    if (!msg.request && msg.code === ERROR.BUSY && !d.conn.welcomed) return; // the server is full: onRefused tells
    if (msg.request === CLIENT.SET_CONSTRAINTS && this.dropStuckPoints()) return;
    const what = msg.request ? ` (${msg.request})` : '';
    d.showRequestError(`${msg.message || msg.code}${what}`);
  }

  /**
   * After the server refused a constraint set: remove the point handles it can never accept (every corner of their
   * triangle is held), say which, and send the rest. False when there were none.
   */
  dropStuckPoints() {
    const { d } = this;
    /** @type {number[]} */
    const stuck = d.points.stuck();
    if (!stuck.length) return false;
    const names = stuck.map((g) => `point ${g + 1}`);
    const list = names.length > 1 ? `${names.slice(0, -1).join(', ')} and ${names.at(-1)}` : names[0];
    for (let k = stuck.length - 1; k >= 0; k--) d.selection.removeGroup(stuck[k]);
    d.refreshSelection(true);
    d.commitConstraints();
    const one = stuck.length === 1;
    d.showRequestError(`Removed ${list}: every corner of ${one ? 'its triangle' : 'their triangles'} is an anchor, a `
      + 'handle or outside the region of interest, so nothing there can move and the server refused '
      + `${one ? 'it' : 'them'}. Place point handles on triangles with a free corner.`);
    return true;
  }
}

/**
 * The note below the view naming what the loaded file could not show (files it names that were not opened with it
 * or were refused, material features, textures left out); it stays until dismissed or another mesh is loaded.
 * @param {string|null} meshName
 * @param {string[]} notes
 */
export function showLoadNote(meshName, notes) {
  const box = document.getElementById('load-note');
  const text = document.getElementById('load-note-text');
  if (!box || !text) return;
  text.textContent = notes.length ? `${meshName ? `${meshName}: ` : ''}${notes.join('; ')}.` : '';
  box.hidden = !notes.length;
  const close = document.getElementById('load-note-close');
  if (close) close.onclick = () => { box.hidden = true; };
}
