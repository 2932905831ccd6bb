// ARAP Studio: wires the connection, the 3D view, the selection tools, the gizmo and the side panel.
import './style.css';
import { createConnection } from './connection.js';
import {
  checkMeshFile, downloadConstraints, downloadExport, installDropTarget, readConstraintsFile,
} from './files.js';
import { HeatMap } from './heatmap.js';
import { describedKeys, Help } from './help.js';
import { installTestHook } from './hook.js';
import { installHud } from './hud.js';
import { SessionKeeper } from './keeper.js';
import { ignoreTypeAhead, installShortcuts, releaseFocusAfterPointerUse } from './keys.js';
import { installManipulation } from './manipulate.js';
import { MirrorEditing } from './mirror.js';
import { Panel } from './panel.js';
import { LivePose } from './livepose.js';
import { installPanelFold } from './panelfold.js';
import { PaintModes } from './paintmodes.js';
import { PointHandles } from './pointhandles.js';
import { CLIENT, ERROR, meshArrays, PROTOCOL_VERSION, SERVER } from './protocol.js';
import { constraintsKey, constraintsMessage, Selection } from './selection.js';
import { builtinSource, fileSource } from './snapshot.js';
import { UpdateStats } from './stats.js';
import { onSessionRestored } from './restore.js';
import { addSnapshotPart } from './autosave.js';
import { Timeline } from './timeline.js';
import { installSurfaceControls, SurfaceSelection } from './surface.js';
import { appearanceArrays } from './texture.js';
import { SelectionTools } from './tools.js';
import { Viewer } from './viewer.js';

const viewer = new Viewer(document.getElementById('view'));
const livePose = new LivePose(viewer, (w, ms) => shapeApplied(w, ms));
const selection = new Selection();
const mirror = new MirrorEditing({ viewer, selection, tell: (text) => panel.showStatus(text, 'info', 6000) });
const app = {
  ready: false,
  incompatible: false, // the server speaks another protocol version
  meshName: null,
  nFaces: 0,
  /** @type {Int32Array|null} */
  vertexMap: null, // mesh vertex of each vertex of the mesh file, when repair renumbered them
  repaired: false, // repair changed the mesh (its triangles are not the file's)
  limits: { max_upload_bytes: 0, max_vertices: 0 },
  frameMs: [], // JavaScript time spent applying each vertices frame applied (drawing excluded)
  meshMs: NaN, // JavaScript time spent showing the last mesh message (drawing excluded)
  uploadAt: {}, // wall-clock times (ms since the epoch) of the last upload's steps on this page
  builtins: [],
  role: 'handle',
  lastSeq: -1,
  groupMap: [], // server handle group k = client group groupMap[k]
  sentKey: null, // constraintsKey of the last set_constraints not yet echoed by a state
  sentVersion: -1, // selection.version that set_constraints carried
  syncedVersion: -1, // selection.version known to match the server's constraints
  serverKey: '',
  serverTransforms: [], // the transforms of the server's handle groups (last state): one per group a drag moves
  errors: [],
  messages: 0,
  canUndo: false,
  canRedo: false,
  params: {},
  busyFor: null,
  awaitingState: false, // an end_drag whose state has not arrived yet
  lastHistory: CLIENT.UNDO, // the last history request sent (undo or redo)
  refusal: null, // why the server refused the last constraint set, until one is accepted
  errorVersion: -1, // selection.version when a request's error was shown (cleared by a later accepted set)
  brush: { screen: 24, world: 4 },
  serverGroups: [], // the handle groups of the server's constraint set (last state), point handles excluded
  source: null, // where the current mesh came from (snapshot.js)
};

const keeper = new SessionKeeper({
  app,
  selection,
  viewer,
  get panel() {
    return panel;
  },
  send,
  requestMesh,
  get gizmo() {
    return gizmo;
  },
  applySelection: applySavedSelection,
  offerParent: document.getElementById('viewport'),
});

const { gizmo, transformUi } = installManipulation({
  app, viewer, selection, mirror, connection: () => conn,
  status: (...a) => panel.showStatus(...a), hush: () => panel.hideStatus(), changed: () => keeper.touch(),
  refused: (text) => showRequestError(text), hint: (text) => panel.hint(text, 5000),
});
const tools = new SelectionTools(viewer, {
  isGizmoActive: () => gizmo.active,
  onPaint: (indices, subtract) => {
    if (mirror.paint(indices, app.role, modes.subtract(app.role, subtract))) refreshSelection(false);
  },
  onStrokeEnd: () => commitConstraints(),
  graph: () => surface.graph(),
  picking: () => app.role === 'point',
  onPick: (hit, subtract) => points.pick(hit, subtract),
});
const points = new PointHandles({ viewer, selection, changed: selectionEdited, weight: () => modes.weight() });
const modes = new PaintModes({ selection, setRole, onWeightProblem: (text) => panel.showStatus(text, 'error', 5000) });
const surface = new SurfaceSelection({
  viewer, selection, role: () => app.role, changed: selectionEdited, paint: (...a) => mirror.paint(...a),
});
const heat = new HeatMap({ viewer, send, role: () => selection.role, restore: () => refreshSelection(false) });
const help = new Help();
viewer.attachControls(); // after the gizmo and the tools, so they see pointer events first

const timeline = new Timeline({
  blocked: timelineBlocked,
  handleGroups: () => app.serverGroups,
  transforms: () => gizmo.transformsFor(app.groupMap),
  matrixOf: (g) => gizmo.transformsFor(app.groupMap)[g],
  positions: () => viewer.positions,
  drag: (transforms) => {
    gizmo.setTransforms(transforms, app.groupMap);
    conn.drag(transforms);
  },
  endDrag: () => {
    conn.endDrag();
    app.awaitingState = true;
  },
  send,
  download: downloadExport,
  changed: () => keeper.touch(),
  say: (text, kind) => panel.showStatus(text, kind, kind === 'error' ? 8000 : 4000),
});
addSnapshotPart('timeline', () => timeline.snapshot());
let lostTimeline = null; // the keyframes when the connection went away, put back with the session
onSessionRestored((snap) => timeline.restore(snap.timeline ?? lostTimeline));

/** Why the timeline cannot pose the handles now (null: it can). */
function timelineBlocked() {
  if (!app.ready || !conn.open) return 'not connected to the studio server';
  if (gizmo.dragging) return 'a drag is under way';
  if (app.sentKey !== null) return 'the new selection is still being set up';
  if (app.refusal) return 'the server refused the current selection';
  if (!app.serverGroups.length) return 'paint a handle group first (keyframes pose handle groups)';
  return null;
}

const stats = new UpdateStats({ panel: () => panel, latencyMs: () => conn.lastLatencyMs });

const conn = createConnection({
  onOpen: () => {
    panel.clearStatus('preparing');
    panel.setConnection('open');
    panel.setEnabled(true);
    roleControls();
    panel.setHistory(app.canUndo, app.canRedo);
  },
  onClose: () => {
    lostTimeline = timeline.snapshot();
    timeline.pause();
    app.ready = false;
    app.awaitingState = false;
    keeper.connectionLost();
    panel.connectionLost();
  },
  onRefused: ({ reason, delayMs }) => {
    app.ready = false;
    app.awaitingState = false;
    panel.serverFull(reason, delayMs, keeper.keepsWork);
  },
  onRetry: ({ attempt, delayMs }) => panel.setConnection('reconnecting', { attempt, delayMs }),
  onWaiting: () => panel.preparingSolver(),
  onMessage: (msg) => handleMessage(msg),
});

function setBusy(text, forType) {
  app.busyFor = text ? forType : null;
  panel.setBusy(text);
}

/** @param {import('./protocol.js').ClientMessage} msg @returns {boolean} */
function send(msg) {
  // apply makes the shape the new rest pose and the pose of the constraints: keyframes are carried over to it
  const current = msg.type === CLIENT.APPLY ? gizmo.transformsFor(app.groupMap) : null;
  if (!conn.send(msg)) {
    notConnected();
    return false;
  }
  if (current) timeline.rebase(current, app.serverGroups.length);
  keeper.sent(msg);
  return true;
}

/** Say that nothing can be sent, unless the status bar already says why (connection lost, server full). */
function notConnected() {
  if (!panel.showing('connection')) panel.showStatus('Not connected to the studio server.', 'error');
}

/** Undo or redo (`type`: CLIENT.UNDO or CLIENT.REDO); a step there is none of says so instead. */
function stepHistory(type) {
  const undo = type === CLIENT.UNDO;
  if (!conn.open) {
    notConnected();
    return false;
  }
  // a drag or selection under way (its state not back yet) may make a step where the last state had none
  const pending = app.awaitingState || app.sentKey !== null || gizmo.dragging;
  if (app.ready && !pending && !(undo ? app.canUndo : app.canRedo)) {
    panel.hint(undo ? 'Nothing to undo.' : 'Nothing to redo.', 2000);
    return false;
  }
  app.lastHistory = type;
  if (!send({ type })) return false;
  // busy until the state that answers it: the shape and the gizmo move back, so a drag must wait for them
  setBusy(undo ? 'Undoing…' : 'Redoing…', SERVER.STATE);
  return true;
}

/** Grow or shrink the current role by a ring from the keyboard; says so when there is nothing to grow. */
function ringKey(shrink) {
  if (surface.ring(shrink)) return;
  const what = app.role === 'point' ? 'Point handles have no rings' : 'Nothing of the current role to '
    + `${shrink ? 'shrink' : 'grow'}: paint some first`;
  panel.hint(`${what} (+ and − grow and shrink the painted role by one ring).`);
}

/** Show the error of a request (or a refused drag): it goes once a later constraint set is accepted. */
function showRequestError(text) {
  app.errorVersion = selection.version;
  panel.showStatus(text, 'error', 0, 'request');
}

// ------------------------------------------------------------------ selection

function selectionEdited() {
  refreshSelection(true);
  commitConstraints();
}

function refreshSelection(full = true) {
  viewer.updateColors(selection.roiCount ? selection.roi : null, selection.role, selection.stiff,
    app.role === 'stiffness' ? 0.9 : 0.35);
  heat.paint();
  points.rebuild();
  gizmo.syncGroups(selection.groups.length);
  if (full) updateGroupsUi();
  else scheduleGroupsUi();
}

let groupsUiQueued = false;
function scheduleGroupsUi() {
  if (groupsUiQueued) return;
  groupsUiQueued = true;
  setTimeout(() => {
    groupsUiQueued = false;
    updateGroupsUi();
  }, 100);
}

function updateGroupsUi() {
  keeper.touch();
  const counts = selection.counts();
  panel.setGroups(selection.groups, selection.activeGroup, counts, viewer.nVertices);
  help.guideProgress({ anchors: counts.fixed > 0, handle: counts.groups.some((c) => c > 0) });
  const anchor = points.anchor(selection.activeGroup);
  if (!gizmo.dragging) gizmo.attach(selection.activeGroup, anchor.indices, anchor.weights);
  points.refresh();
}

/**
 * Send the local selection as the session's constraint set; `targets` (a Map from handle vertex to [x, y, z],
 * from a loaded file) moves the handles there, as `pointTargets` (one [x, y, z] or null per point handle) does the
 * point handles. `force` sends it even when the server seems to hold it already.
 */
function commitConstraints(targets = null, force = false, pointTargets = null) {
  updateGroupsUi();
  if (!app.ready) return;
  const c = selection.toConstraints();
  const key = constraintsKey(c);
  const moving = !!targets || !!pointTargets?.some((t) => t);
  if (key === app.serverKey && app.sentKey === null && !moving && !force) {
    // the server holds this selection already (e.g. a refused point handle was taken away again): drags must
    // carry its groups, not those of the set it refused
    const regrouped = c.groupMap.join() !== app.groupMap.join();
    app.groupMap = c.groupMap;
    app.syncedVersion = selection.version;
    if (regrouped && !gizmo.dragging) gizmo.setTransforms(app.serverTransforms, app.groupMap);
    return;
  }
  // the new set's pose is the current shape: keyframes are made relative to it
  timeline.rebase(gizmo.transformsFor(app.groupMap), c.handle_groups.length);
  app.groupMap = c.groupMap;
  app.sentKey = key;
  app.sentVersion = selection.version;
  gizmo.resetTransforms();
  if (send(constraintsMessage(c, targets, pointTargets))) setBusy('Updating constraints…', SERVER.STATE);
}

// ------------------------------------------------------------------ messages

function handleMessage(msg) {
  app.messages++;
  if (msg.type !== SERVER.WELCOME && app.incompatible) return undefined;
  keeper.touch();
  // a shape received and not drawn yet is shown before anything that may read it; settling progress is not such
  if (msg.type === SERVER.MESH) livePose.reset();
  else if (msg.type !== SERVER.VERTICES && !(msg.type === SERVER.SETTLE && msg.status === 'settling')) livePose.flush();
  switch (msg.type) {
    case SERVER.WELCOME:
      return onWelcome(msg);
    case SERVER.MESH:
      return onMesh(msg);
    case SERVER.APPEARANCE:
      return onAppearance(msg);
    case SERVER.VERTICES:
      return onVertices(msg);
    case SERVER.STATE:
      return onState(msg);
    case SERVER.SETTLE:
      if (Number.isFinite(msg.energy)) stats.noteEnergies([msg.energy]);
      return panel.setSettle(msg);
    case SERVER.CONSTRAINTS: // the document carries the mirror pairs of its handle groups in "meta"
      if (app.repaired && msg.document?.points?.length) return showRequestError(POINTS_NOT_SAVED(app.meshName));
      return panel.showStatus(downloadConstraints(mirror.documentWithPartners(msg.document, app.groupMap),
        app.meshName), 'info', 2500);
    case SERVER.EXPORT:
      return panel.showStatus(downloadExport(msg), 'info', 3000);
    case SERVER.ANIMATION_PROGRESS:
    case SERVER.ANIMATION:
      return timeline.received(msg);
    case SERVER.DISTORTION:
      return heat.received(msg);
    case SERVER.ERROR:
      return onError(msg);
    default:
      return undefined;
  }
}

/**
 * Why point handles are not saved for a mesh that repair changed (the server says the same of a mesh it repaired
 * itself; a session restored from the PLY of such a mesh is one it did not repair).
 */
const POINTS_NOT_SAVED = (name) => `Point handles cannot be saved in a constraints document for ${name}: they refer `
  + 'to the triangles of the mesh as repaired when it was loaded, not to the file\'s, and arap deform refuses point '
  + 'handles on a mesh that repair changes; remove the point handles, or repair the mesh file first (arap info shows '
  + 'what repair changes).';

function onWelcome(msg) {
  app.incompatible = msg.protocol !== PROTOCOL_VERSION;
  if (app.incompatible) {
    // a page left open across an upgrade of the server: its messages would be misread
    app.ready = false;
    panel.protocolMismatch(PROTOCOL_VERSION, msg.protocol);
    return;
  }
  keeper.welcomed();
  app.builtins = msg.builtin_meshes || [];
  app.limits = { ...app.limits, ...(msg.limits || {}) };
  panel.setBuiltins(app.builtins, app.meshName);
  panel.setParams(msg.params);
  if (msg.params) app.params = { ...msg.params };
  setBusy('Loading mesh…', SERVER.MESH);
}

function onMesh(msg) {
  const t0 = performance.now();
  app.uploadAt.received = performance.timeOrigin + t0;
  const { positions, faces, vertexMap } = meshArrays(msg.frame);
  viewer.setMesh(positions, faces);
  panel.setSurfaces(viewer.surfaces, viewer.surface); // plain until an appearance says otherwise
  livePose.reset();
  selection.reset(msg.n_vertices);
  gizmo.syncGroups(1);
  gizmo.resetTransforms();
  transformUi.meshChanged();
  app.meshName = msg.name;
  app.nFaces = msg.n_faces;
  app.vertexMap = vertexMap; // constraints documents name the file's vertices (numbering.js)
  app.repaired = (msg.report || []).length > 0;
  app.lastSeq = -1;
  app.groupMap = [];
  app.serverTransforms = [];
  app.serverGroups = [];
  timeline.clear();
  app.sentKey = null;
  app.syncedVersion = selection.version;
  app.refusal = null;
  app.errorVersion = -1;
  app.serverKey = constraintsKey({ roi: null, fixed: [], handle_groups: [] });
  app.ready = true;
  stats.reset();
  panel.meshLoaded(msg);
  refreshSelection(true);
  heat.meshChanged();
  setBusy(null);
  mirror.meshChanged(positions, faces); // after the status line: it may say that no symmetry was found
  keeper.meshArrived(msg, positions, faces);
  if (app.source?.repaired) app.repaired = true; // a PLY written from a repaired mesh: still not the file's triangles
  app.meshMs = performance.now() - t0;
  app.uploadAt.shown = performance.timeOrigin + performance.now();
  requestAnimationFrame(() => { // after the viewer's own frame callback: the mesh has been drawn once
    app.uploadAt.drawn = performance.timeOrigin + performance.now();
  });
}

/**
 * The mesh file's look, right after its mesh: its texture on a render mesh or its vertex colours, and the panel's
 * surface choice; notes say what is not shown.
 */
function onAppearance(msg) {
  viewer.setLook(appearanceArrays(msg.frame, viewer.nVertices));
  panel.setSurfaces(viewer.surfaces, viewer.surface);
  refreshSelection(false);
  if (msg.notes?.length) panel.showStatus(`${app.meshName}: ${msg.notes.join('; ')}.`, 'info', 10000);
}

/** Draw the surface with its texture, its vertex colours or plain (the panel's Surface control). */
function setSurface(mode) {
  viewer.setSurface(mode);
  panel.setSurfaces(viewer.surfaces, viewer.surface);
  refreshSelection(false);
}

/** A vertices frame: kept until the next animation frame, when the newest one received is drawn. */
function onVertices(msg) {
  if (livePose.receive(msg.frame, msg) && msg.iterations > 0) stats.received(msg);
}

/**
 * The newest shape received was applied (livePose): what depends on it follows. `w.seq` is the newest request it
 * answers (-1: only frames the server sent on its own, settling or undo).
 * @param {import('./livepose.js').Waiting} w
 * @param {number} ms
 */
function shapeApplied(w, ms) {
  app.frameMs.push(ms);
  if (app.frameMs.length > 256) app.frameMs.shift();
  heat.shapeChanged();
  if (w.seq >= 0) app.lastSeq = w.seq;
  gizmo.recenter();
  points.refresh();
  if (w.solved) stats.frame(w.solved); // not for a pose change without a solve (undo, reset)
}

function onState(msg) {
  if (app.awaitingState) help.guideProgress({ drag: true }); // the state that answers the end of a drag
  app.awaitingState = false;
  mirror.stateArrived(msg.rest_id);
  app.canUndo = !!msg.can_undo;
  app.canRedo = !!msg.can_redo;
  panel.setHistory(app.canUndo, app.canRedo);
  panel.setParams(msg.params);
  if (msg.params) app.params = { ...msg.params };
  if (msg.stats) panel.setStats(msg.stats);
  const c = msg.constraints || { roi: null, fixed: [], handle_groups: [] };
  const key = constraintsKey(c);
  app.serverKey = key;
  if (app.sentKey === null && keeper.restore.isPinStep(key) && stepOverPin(msg)) return;
  if (app.sentKey !== null && key === app.sentKey) {
    app.sentKey = null;
    app.syncedVersion = app.sentVersion;
    app.refusal = null;
    if (app.syncedVersion > app.errorVersion) panel.clearStatus('request'); // the error no longer holds
  } else if (app.sentKey === null && key === constraintsKey(selection.toConstraints())) {
    app.groupMap = selection.toConstraints().groupMap; // the server's groups are the ones shown
  } else if (app.sentKey === null) {
    // the server's constraints changed under us (undo/redo, loaded document): adopt them
    selection.fromConstraints(c);
    mirror.repair();
    app.groupMap = selection.toConstraints().groupMap;
    app.syncedVersion = selection.version;
    app.refusal = null;
    refreshSelection(true);
  }
  app.serverTransforms = msg.transforms || [];
  app.serverGroups = c.handle_groups || [];
  if (!gizmo.dragging) gizmo.setTransforms(msg.transforms, app.groupMap);
  if (app.busyFor === SERVER.STATE) setBusy(null);
  updateGroupsUi();
  keeper.stateArrived(app.sentKey === null);
}

/**
 * Undo or redo reached the constraint set with which a restore put the saved shape back (every moved vertex a
 * handle): not a state the user made, so go on in the same direction (the other one when that is not possible).
 * False when neither is possible (the state is then shown as it is).
 */
function stepOverPin(msg) {
  const can = (t) => !!(t === CLIENT.UNDO ? msg.can_undo : msg.can_redo);
  const ahead = app.lastHistory;
  const back = ahead === CLIENT.UNDO ? CLIENT.REDO : CLIENT.UNDO;
  const type = can(ahead) ? ahead : can(back) ? back : null;
  if (type === null) return false;
  app.canUndo = !!msg.can_undo;
  app.canRedo = !!msg.can_redo;
  return conn.send({ type }); // lastHistory stays: a further step over it goes the way the user went
}

function onError(msg) {
  app.errors.push({ code: msg.code, message: msg.message, request: msg.request ?? null });
  if (msg.request === CLIENT.SET_CONSTRAINTS) {
    app.sentKey = null;
    app.refusal = msg.message || msg.code;
  }
  if (msg.request === CLIENT.SET_PARAMS) panel.setParams(app.params); // the controls show what the server still uses
  if (app.busyFor) setBusy(null);
  if (msg.request === CLIENT.END_DRAG) app.awaitingState = false;
  if (msg.request === CLIENT.GET_DISTORTION) heat.failed();
  if (msg.request === CLIENT.EXPORT_ANIMATION) timeline.failed(msg.message || msg.code);
  keeper.errorArrived(msg);
  if (!msg.request && msg.code === ERROR.BUSY && !conn.welcomed) return; // the server is full: onRefused tells
  if (msg.request === CLIENT.SET_CONSTRAINTS && dropStuckPoints()) return;
  const what = msg.request ? ` (${msg.request})` : '';
  showRequestError(`${msg.message || msg.code}${what}`);
}

/**
 * After the server refused a constraint set: remove the point handles it can never accept (every corner of their
 * triangle is held), say which, and send the rest. False when there were none.
 */
function dropStuckPoints() {
  const stuck = points.stuck();
  if (!stuck.length) return false;
  const names = stuck.map((g) => `point ${g + 1}`);
  const list = names.length > 1 ? `${names.slice(0, -1).join(', ')} and ${names.at(-1)}` : names[0];
  for (let k = stuck.length - 1; k >= 0; k--) selection.removeGroup(stuck[k]);
  refreshSelection(true);
  commitConstraints();
  const one = stuck.length === 1;
  showRequestError(`Removed ${list}: every corner of ${one ? 'its triangle' : 'their triangles'} is an anchor, a `
    + 'handle or outside the region of interest, so nothing there can move and the server refused '
    + `${one ? 'it' : 'them'}. Place point handles on triangles with a free corner.`);
  return true;
}

// ------------------------------------------------------------------ actions

/** Load a mesh source (snapshot.js): a built-in model by name, or a mesh file's bytes. */
function requestMesh(source) {
  const ok = source.kind === 'builtin'
    ? conn.send({ type: CLIENT.LOAD_BUILTIN, name: source.name })
    : conn.sendBinary({ type: CLIENT.UPLOAD, filename: source.filename }, source.bytes);
  if (!ok) {
    notConnected();
    return false;
  }
  if (source.kind !== 'builtin') app.uploadAt.sent = performance.timeOrigin + performance.now();
  keeper.meshRequested(source);
  setBusy(`Loading ${source.kind === 'builtin' ? source.name : source.filename}…`, SERVER.MESH);
  return true;
}

function uploadFile(file) {
  const problem = checkMeshFile(file, app.limits.max_upload_bytes);
  if (problem) {
    app.errors.push({ code: 'client_check', message: problem, request: CLIENT.UPLOAD });
    panel.showStatus(problem, 'error');
    return;
  }
  if (!keeper.confirmReplace(file.name)) return;
  app.uploadAt = { chosen: performance.timeOrigin + performance.now() };
  file.arrayBuffer().then((buf) => {
    app.uploadAt.read = performance.timeOrigin + performance.now();
    requestMesh(fileSource(file.name, buf));
  });
}

function applySavedSelection(snap) {
  selection.fromConstraints({ roi: snap.roi, fixed: snap.fixed, handle_groups: snap.groups, stiffness: snap.stiffness },
    snap.groupPoints);
  selection.activeGroup = Math.max(0, Math.min(snap.activeGroup ?? 0, selection.groups.length - 1));
  mirror.setPartners(snap.partners);
  refreshSelection(true);
  commitConstraints(null, true);
  gizmo.restorePivots(snap.pivots); // after the new constraint set made the restored shape every group's frame
}

/**
 * A constraints document with keyframes: the document whose handles start at the positions the keyframes' transforms
 * apply to (`keyframe_base`, else their rest positions), and the keyframes in the timeline's form; null without
 * keyframes. Throws when its keyframes cannot be shown on the timeline.
 */
function keyframedDocument(text) {
  let doc;
  try {
    doc = JSON.parse(text);
  } catch {
    return null; // readConstraintsFile says what is wrong
  }
  if (!doc || !Array.isArray(doc.keyframes) || !doc.keyframes.length || !Array.isArray(doc.handles)) return null;
  if (!doc.keyframes.every((k) => Array.isArray(k?.transforms) && Number.isFinite(k.time) && k.time >= 0)) {
    throw new Error('the timeline shows keyframes of transforms at times from 0 s on; this document has others');
  }
  const rest = keeper.rest;
  const base = Array.isArray(doc.keyframe_base) ? doc.keyframe_base : doc.handles.map((i) => {
    const v = app.vertexMap ? app.vertexMap[i] : i;
    return [rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]];
  });
  const keys = doc.keyframes.map((k) => ({
    ms: Math.round(1000 * k.time),
    transforms: k.transforms.map((m) => [0, 1, 2, 3].flatMap((c) => [0, 1, 2, 3].map((r) => Number(m[r][c])))),
  }));
  return { text: JSON.stringify({ ...doc, targets: base }), keys };
}

function loadConstraintsFile(file) {
  file.text().then((text) => {
    const keyed = keyframedDocument(text);
    const read = keyed ? new File([keyed.text], file.name, { type: 'application/json' }) : file;
    return readConstraintsFile(read, viewer.nVertices, app.nFaces, app.vertexMap, app.repaired).then((c) => {
      selection.fromConstraints(c);
      mirror.setPairs(c.partners);
      refreshSelection(true);
      commitConstraints(c.targets, false, c.points.map((p) => p.target ?? null));
      if (keyed) {
        const pivots = c.handle_groups.map((g) => {
          const sum = [0, 0, 0];
          for (const i of g) c.targets.get(i).forEach((x, d) => (sum[d] += x));
          return sum.map((x) => x / Math.max(g.length, 1));
        });
        timeline.load(keyed.keys, pivots);
      }
    });
  }).catch((err) => {
    app.errors.push({ code: 'client_check', message: err.message, request: CLIENT.SET_CONSTRAINTS });
    panel.showStatus(err.message, 'error');
  });
}

function setRole(role) {
  app.role = role;
  panel.setSegment('role-seg', 'role', role);
  modes.showRole(role);
  refreshSelection(false);
  roleControls();
}

/** The controls that depend on the role: Invert where the role can be inverted, the stiffness brush's slider. */
function roleControls() {
  /** @type {HTMLButtonElement} */ (document.getElementById('btn-invert')).disabled = !panel.enabled
    || !selection.invertible(app.role);
  modes.enable(panel.enabled);
}

function setTool(tool) {
  tools.setTool(tool);
  panel.setSegment('tool-seg', 'tool', tool);
}

function setBrushUnits(units) {
  tools.units = units;
  panel.setBrushRadius(units, app.brush[units]);
}

function setGizmoMode(mode) {
  gizmo.setMode(mode);
  panel.setSegment('gizmo-seg', 'gizmo', mode);
}

const panel = new Panel({
  send,
  loadBuiltin: (name) => {
    if (!name || name === app.meshName) return;
    if (keeper.confirmReplace(name)) requestMesh(builtinSource(name));
    else panel.setCurrentModel(app.meshName);
  },
  uploadFile,
  loadConstraintsFile,
  setTool,
  setRole,
  setGizmoMode,
  setBrushRadius: (v) => {
    app.brush[tools.units] = v;
    if (tools.units === 'world') tools.worldRadiusFrac = v / 100;
    else tools.radiusPx = v;
    panel.setBrushRadius(tools.units, v);
  },
  setBrushUnits,
  setFrontOnly: (on) => (tools.frontOnly = on),
  clearRole: () => {
    mirror.clear(app.role);
    selectionEdited();
  },
  invertRole: () => selection.invert(app.role) && selectionEdited(),
  clearAll: () => {
    selection.clear('erase');
    selectionEdited();
  },
  newGroup: () => {
    selection.addGroup();
    setRole('handle');
    refreshSelection(true);
  },
  removeGroup: (g) => {
    selection.removeGroup(g);
    selectionEdited();
  },
  selectGroup: (g) => {
    selection.activeGroup = g;
    setRole(selection.groups[g]?.point ? 'point' : 'handle');
    updateGroupsUi();
  },
  undo: () => stepHistory(CLIENT.UNDO),
  redo: () => stepHistory(CLIENT.REDO),
  setParams: (p) => send({ type: CLIENT.SET_PARAMS, ...p }),
  saveConstraints: () => send({ type: CLIENT.GET_CONSTRAINTS, ...(timeline.messageFields() ?? {}) }),
  setFlatShading: (on) => viewer.setFlatShading(on),
  setWireframe: (on) => viewer.setWireframe(on),
  setSurface,
  fit: () => viewer.fit(),
  reconnect: () => {
    panel.setConnection('connecting');
    panel.hideStatus();
    conn.connect();
  },
});

// ------------------------------------------------------------------ keyboard and drop

installShortcuts({
  undo: () => stepHistory(CLIENT.UNDO),
  redo: () => stepHistory(CLIENT.REDO),
  keys: describedKeys({
    w: () => setGizmoMode('translate'),
    e: () => setGizmoMode('rotate'),
    b: () => setTool('brush'),
    x: () => setTool('box'),
    o: () => setTool('orbit'),
    f: () => viewer.fit(),
    n: () => panel.actions.newGroup(),
    1: () => setRole('roi'),
    2: () => setRole('fixed'),
    3: () => setRole('handle'),
    4: () => setRole('erase'),
    5: () => setRole('point'),
    6: () => setRole('stiffness'),
    '+': () => ringKey(false),
    '=': () => ringKey(false),
    '-': () => ringKey(true),
    h: () => heat.setOn(!heat.on),
    m: () => mirror.setOn(!mirror.on),
    k: () => timeline.addKeyframe(),
    '?': () => help.toggle(),
    escape: () => (help.shown ? help.hide() : panel.hideStatus()),
    ...transformUi.keys,
  }),
  unbound: (key) => panel.hint(`“${key}” is not a shortcut; press ? for the list of keys.`),
});
installSurfaceControls(surface, tools, (text) => panel.showStatus(text, 'info', 3000));
installHud(document.getElementById('hud'), document.querySelector('#hud .hud-head'), document.getElementById('hud-toggle'));
installPanelFold(document.getElementById('panel'), /** @type {HTMLButtonElement} */ (document.getElementById('btn-panel')));
ignoreTypeAhead(document.getElementById('builtin-select'));
releaseFocusAfterPointerUse(document.getElementById('panel'));

installDropTarget(document.getElementById('viewport'), document.getElementById('drop-overlay'), uploadFile);

installTestHook({ app, viewer, livePose, selection, gizmo, conn, keeper, points, mirror, transformUi, timeline });

// ------------------------------------------------------------------ start

panel.setEnabled(false);
panel.setConnection('connecting');
setTool('brush');
setRole('handle');
setGizmoMode('translate');
panel.setBrushRadius('screen', app.brush.screen);
updateGroupsUi();
conn.connect();
keeper.offerSaved().catch((err) => panel.showStatus(`Saved sessions cannot be read: ${err.message || err}`, 'error'));
