// ARAP Studio: wires the connection, the 3D view, the selection tools, the gizmo and the side panel. The page's
// state lives in small stores (stores/), the constraint-sync protocol in ConstraintSync (constraintsync.js) and the
// handling of the server's messages in ServerMessages (messages.js); this module builds the pieces and connects them.
// Each piece is built after the pieces it needs, so none is reached before it exists: the panel's readouts and the
// connection are built first (the panel's controls and the connection's handlers are bound once everything is
// built), and where a piece must tell one built after it, it emits one of the studio's events (events.js).
import './style.css';
import { createConnection } from './connection.js';
import { ConstraintSync } from './constraintsync.js';
import { downloadExport, installDropTarget } from './files.js';
import { HeatMap } from './heatmap.js';
import { describedKeys, Help } from './help.js';
import { installTestHook } from './hook.js';
import { installHud } from './hud.js';
import { SessionKeeper } from './keeper.js';
import { ignoreTypeAhead, installShortcuts, releaseFocusAfterPointerUse } from './keys.js';
import { loadConstraintsFile } from './loaddocument.js';
import { installManipulation } from './manipulate.js';
import { MeshLoading } from './meshloading.js';
import { Requests, showRequestError } from './requests.js';
import { ServerMessages } from './messages.js';
import { MirrorEditing } from './mirror.js';
import { Panel } from './panel.js';
import { LivePose } from './livepose.js';
import { installPanelFold } from './panelfold.js';
import { PaintModes } from './paintmodes.js';
import { PointHandles } from './pointhandles.js';
import { isPicture } from './picturemode.js';
import { installPinRotation } from './pinrotate.js';
import { CLIENT, SERVER } from './protocol.js';
import { constraintsMessage, Selection } from './selection.js';
import { SelectionView } from './selectionview.js';
import { UpdateStats } from './stats.js';
import { onSessionRestored } from './restore.js';
import { addSnapshotPart } from './autosave.js';
import { StudioEvents } from './events.js';
import { Diagnostics } from './stores/diagnostics.js';
import { HistoryStore } from './stores/historystore.js';
import { MeshStore } from './stores/meshstore.js';
import { ParamStore } from './stores/paramstore.js';
import { ToolStore } from './stores/toolstore.js';
import { Timeline } from './timeline.js';
import { installSurfaceControls, SurfaceSelection } from './surface.js';
import { SelectionTools } from './tools.js';
import { Viewer } from './viewer.js';

/** @param {string} id */
const byId = (id) => /** @type {HTMLElement} */ (document.getElementById(id));

const mesh = new MeshStore();
const history = new HistoryStore();
const params = new ParamStore();
const diagnostics = new Diagnostics();
const painting = new ToolStore();
const events = new StudioEvents();

const viewer = new Viewer(byId('view'));
const panel = new Panel(); // its controls act once bound to the studio's actions, below
const conn = createConnection(); // it tells what happens once the pieces that listen are built, below
const help = new Help();
const livePose = new LivePose(viewer, (w, ms) => events.emit('shapeApplied', w, ms));
const selection = new Selection();
const mirror = new MirrorEditing({ viewer, selection, tell: (text) => panel.showStatus(text, 'info', 6000) });
const sync = new ConstraintSync(selection, {
  replaceSelection: (c) => {
    selection.fromConstraints(c);
    mirror.repair();
  },
  selectionReplaced: () => events.emit('selectionChanged', true),
  requestErrorCleared: () => panel.clearStatus('request'),
});
const showError = (/** @type {string} */ text) => showRequestError(sync, panel, text);

const { gizmo, transformUi } = installManipulation({
  mesh, history, sync, viewer, selection, mirror, connection: conn,
  status: (...a) => panel.showStatus(...a), hush: () => panel.hideStatus(), changed: () => events.emit('edited'),
  refused: showError, hint: (text) => panel.hint(text, 5000),
});
const requests = new Requests({ mesh, history, sync, conn, panel, gizmo, events });
const send = requests.send.bind(requests);
const setBusy = requests.setBusy.bind(requests);
const stepHistory = requests.stepHistory.bind(requests);

const modes = new PaintModes({ selection, setRole, onWeightProblem: (text) => panel.showStatus(text, 'error', 5000) });
const points = new PointHandles({ viewer, selection, changed: selectionEdited, weight: () => modes.weight() });
const surface = new SurfaceSelection({
  viewer, selection, role: () => painting.role, changed: selectionEdited, paint: (...a) => mirror.paint(...a),
});
const heat = new HeatMap({
  viewer, send, role: () => selection.role, restore: () => events.emit('selectionChanged', false),
});
const tools = new SelectionTools(viewer, {
  isGizmoActive: () => gizmo.active,
  onPaint: (indices, subtract) => {
    if (mirror.paint(indices, painting.role, modes.subtract(painting.role, subtract))) {
      events.emit('selectionChanged', false);
    }
  },
  onStrokeEnd: () => commitConstraints(),
  graph: () => surface.graph(),
  picking: () => painting.role === 'point',
  onPick: (hit, subtract) => points.pick(hit, subtract),
});
viewer.attachControls(); // after the gizmo and the tools, so they see pointer events first

const keeper = new SessionKeeper({
  mesh,
  history,
  params,
  selection,
  viewer,
  panel,
  send,
  requestMesh: (source) => loading.request(source), // the loading asks the keeper before it replaces a mesh
  gizmo,
  applySelection: applySavedSelection,
  offerParent: byId('viewport'),
});
events.on('edited', () => keeper.touch());
events.on('sent', (msg) => keeper.sent(msg));

const shown = new SelectionView({
  viewer, selection, role: () => painting.role, heat, points, gizmo, help, panel, changed: () => keeper.touch(),
});
events.on('selectionChanged', (full) => shown.refresh(full));

/** @type {MeshLoading} */ const loading = new MeshLoading({
  mesh, diagnostics, conn, keeper, panel, setBusy, notConnected: () => requests.notConnected(),
});

const timeline = new Timeline({
  blocked: timelineBlocked,
  handleGroups: () => sync.serverGroups,
  transforms: () => gizmo.transformsFor(sync.groupMap),
  matrixOf: (g) => gizmo.transformsFor(sync.groupMap)[g],
  positions: () => viewer.positions,
  anchor: (g) => (g < sync.serverGroups.length ? { indices: sync.serverGroups[g], weights: null }
    : points.anchor(sync.groupMap[g])),
  drag: (transforms, key) => {
    gizmo.setTransforms(transforms, sync.groupMap);
    conn.drag(transforms, key);
  },
  endDrag: () => {
    conn.endDrag();
    history.dragEnded();
  },
  send,
  download: downloadExport,
  changed: () => keeper.touch(),
  say: (text, kind) => panel.showStatus(text, kind, kind === 'error' ? 8000 : 4000),
});
events.on('sent', (msg) => {
  // apply makes the shape the new rest pose and the pose of the constraints: keyframes are carried over to it
  if (msg.type === CLIENT.APPLY) timeline.rebase(gizmo.transformsFor(sync.groupMap), sync.serverGroups.length);
});
/** @typedef {ReturnType<Timeline['snapshot']>} TimelineSnapshot what the 'timeline' part of a snapshot holds */
addSnapshotPart('timeline', () => timeline.snapshot());
/** @type {TimelineSnapshot} the keyframes when the connection went away, put back with the session */
let lostTimeline = null;
onSessionRestored((snap) => timeline.restore(/** @type {TimelineSnapshot|undefined} */ (snap.timeline) ?? lostTimeline));
// the up axis of the view is kept with the session when it is not the default (Y up), which alone is no edit
addSnapshotPart('view', () => (viewer.upAxis === 'y' ? null : { upAxis: viewer.upAxis }));
onSessionRestored((snap) => {
  const view = /** @type {{upAxis?: unknown}|undefined} */ (snap.view);
  if (view?.upAxis === 'z' || view?.upAxis === 'y') setUpAxis(view.upAxis, false);
});

const stats = new UpdateStats({ panel, latencyMs: () => conn.lastLatencyMs });

const messages = new ServerMessages({
  mesh, history, params, diagnostics, sync, viewer, livePose, selection, gizmo, transformUi, timeline, stats, panel,
  heat, mirror, keeper, help, points, conn, refreshSelection: (full) => shown.refresh(full),
  updateGroupsUi: () => shown.updateList(), setBusy, showRequestError: showError,
  commitConstraints,
});
events.on('shapeApplied', (w, ms) => messages.shapeApplied(w, ms));

conn.listen({
  onOpen: () => {
    panel.clearStatus('preparing');
    panel.setConnection('open');
    panel.setEnabled(true);
    roleControls();
    panel.setHistory(history.canUndo, history.canRedo);
  },
  onClose: () => {
    lostTimeline = timeline.snapshot();
    timeline.pause();
    mesh.connectionLost();
    history.connectionLost();
    keeper.connectionLost();
    panel.connectionLost();
  },
  onRefused: ({ reason, delayMs }) => {
    mesh.connectionLost();
    history.connectionLost();
    panel.serverFull(reason, delayMs, keeper.keepsWork);
  },
  onRetry: ({ attempt, delayMs }) => panel.setConnection('reconnecting', { attempt, delayMs }),
  onWaiting: () => panel.preparingSolver(),
  onMessage: (msg) => messages.handle(msg),
});

// ------------------------------------------------------------------ panel, keyboard and drop

panel.bind({
  send,
  loadBuiltin: (name) => loading.builtin(name),
  uploadFile: (file) => loading.upload(file),
  loadConstraintsFile: (file) => loadConstraintsFile(file, {
    mesh, diagnostics, viewer, selection, mirror, timeline, rest: () => keeper.rest,
    refreshSelection: (full) => shown.refresh(full),
    commit: commitConstraints, say: (text, kind) => panel.showStatus(text, kind),
  }),
  setTool,
  setRole,
  setGizmoMode,
  setBrushRadius: (v) => {
    painting.brushSized(tools.units, v);
    tools.brushSized(v);
    panel.setBrushRadius(tools.units, v);
  },
  setBrushUnits,
  setFrontOnly: (on) => tools.frontOnlyChosen(on),
  clearRole: () => {
    mirror.clear(painting.role);
    selectionEdited();
  },
  invertRole: () => selection.invert(painting.role) && selectionEdited(),
  clearAll: () => {
    selection.clear('erase');
    selectionEdited();
  },
  newGroup: () => {
    selection.addGroup();
    setRole('handle');
    shown.refresh(true);
  },
  removeGroup: (g) => {
    selection.removeGroup(g);
    selectionEdited();
  },
  selectGroup: (g) => {
    selection.groupChosen(g);
    setRole(selection.groups[g]?.point ? 'point' : 'handle');
    shown.updateList();
  },
  undo: () => stepHistory(CLIENT.UNDO),
  redo: () => stepHistory(CLIENT.REDO),
  setParams: (p) => send({ type: CLIENT.SET_PARAMS, ...p }),
  activePin: () => (selection.groups[selection.activeGroup]?.point
    ? selection.groups.slice(0, selection.activeGroup).filter((g) => g.point).length : null),
  saveConstraints: () => send({ type: CLIENT.GET_CONSTRAINTS, ...(timeline.messageFields() ?? {}) }),
  setFlatShading: (on) => viewer.setFlatShading(on),
  setWireframe: (on) => viewer.setWireframe(on),
  setUpAxis,
  setSurface,
  fit: () => viewer.fit(),
  reconnect: () => {
    panel.setConnection('connecting');
    panel.hideStatus();
    conn.connect();
  },
});
installPinRotation({ viewer, gizmo, picture: isPicture, activePin: panel.actions.activePin, send });

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
    delete: () => selection.groups[selection.activeGroup]?.point && panel.actions.removeGroup(selection.activeGroup),
    '?': () => help.toggle(),
    escape: () => (help.shown ? help.hide() : panel.hideStatus()),
    ...transformUi.keys,
  }),
  unbound: (key) => panel.hint(`“${key}” is not a shortcut; press ? for the list of keys.`),
});
installSurfaceControls(surface, tools, (text) => panel.showStatus(text, 'info', 3000));
installHud(byId('hud'), /** @type {HTMLElement} */ (document.querySelector('#hud .hud-head')), byId('hud-toggle'));
installPanelFold(byId('panel'), /** @type {HTMLButtonElement} */ (byId('btn-panel')));
ignoreTypeAhead(byId('builtin-select'));
releaseFocusAfterPointerUse(byId('panel'));

installDropTarget(byId('viewport'), byId('drop-overlay'), (file) => loading.upload(file));

// only the browser tests' build has the hook (vite.config.js): the normal build drops this branch and hook.js with it
if (import.meta.env.MODE === 'e2e') {
  installTestHook({
    mesh, history, params, diagnostics, tools: painting, sync, viewer, livePose, selection, gizmo, conn, keeper, points,
    mirror, transformUi, timeline,
  });
}

// ------------------------------------------------------------------ actions

/** Why the timeline cannot pose the handles now (null: it can). */
function timelineBlocked() {
  if (!mesh.ready || !conn.open) return 'not connected to the studio server';
  if (gizmo.dragging) return 'a drag is under way';
  if (sync.pending) return 'the new selection is still being set up';
  if (sync.refusal) return 'the server refused the current selection';
  if (!sync.groupMap.length) return 'paint a handle group or place a point handle first (keyframes pose them)';
  return null;
}

/**
 * Grow or shrink the current role by a ring from the keyboard; says so when there is nothing to grow.
 * @param {boolean} shrink
 */
function ringKey(shrink) {
  if (surface.ring(shrink)) return;
  const what = painting.role === 'point' ? 'Point handles have no rings' : 'Nothing of the current role to '
    + `${shrink ? 'shrink' : 'grow'}: paint some first`;
  panel.hint(`${what} (+ and − grow and shrink the painted role by one ring).`);
}

// ------------------------------------------------------------------ selection

function selectionEdited() {
  shown.refresh(true);
  commitConstraints();
}

/**
 * Send the local selection as the session's constraint set; `targets` (a Map from handle vertex to [x, y, z],
 * from a loaded file) moves the handles there, as `pointTargets` (one [x, y, z] or null per point handle) does the
 * point handles. `force` sends it even when the server seems to hold it already.
 * @param {Map<number, number[]>|null} [targets]
 * @param {boolean} [force]
 * @param {(number[]|null|undefined)[]|null} [pointTargets]
 */
function commitConstraints(targets = null, force = false, pointTargets = null) {
  shown.updateList();
  if (!mesh.ready) return;
  const c = selection.toConstraints();
  const moving = !!targets || !!pointTargets?.some((t) => t);
  const held = sync.held(c, moving || force);
  if (held) {
    if (held.regrouped && !gizmo.dragging) gizmo.setTransforms(sync.serverTransforms, sync.groupMap);
    return;
  }
  // the new set's pose is the current shape: keyframes are made relative to it
  timeline.rebase(gizmo.transformsFor(sync.groupMap), c.handle_groups.length);
  sync.sending(c);
  gizmo.resetTransforms();
  if (send(constraintsMessage(c, targets, pointTargets))) setBusy('Updating constraints…', SERVER.STATE);
}

// ------------------------------------------------------------------ actions

/**
 * Draw the Y or the Z axis up (the view turns; the data keep their coordinates).
 * @param {'y'|'z'} axis
 * @param {boolean} [touch] a change of the user's, to be saved with the session
 */
function setUpAxis(axis, touch = true) {
  viewer.setUpAxis(axis);
  /** @type {HTMLSelectElement} */ (byId('up-axis')).value = viewer.upAxis;
  if (touch) keeper.touch();
}

/**
 * Draw the surface with its texture, its vertex colours or plain (the panel's Surface control).
 * @param {Parameters<Viewer['setSurface']>[0]} mode
 */
function setSurface(mode) {
  viewer.setSurface(mode);
  panel.setSurfaces(viewer.surfaces, viewer.surface);
  shown.refresh(false);
}

function applySavedSelection(/** @type {import('./autosave.js').Snapshot} */ snap) {
  selection.fromConstraints({ roi: snap.roi, fixed: snap.fixed, handle_groups: snap.groups, stiffness: snap.stiffness },
    snap.groupPoints);
  selection.groupChosen(Math.max(0, Math.min(snap.activeGroup ?? 0, selection.groups.length - 1)));
  mirror.setPartners(snap.partners);
  shown.refresh(true);
  commitConstraints(null, true);
  gizmo.restorePivots(snap.pivots); // after the new constraint set made the restored shape every group's frame
}

function setRole(/** @type {string} */ role) {
  painting.roleChosen(role);
  panel.setSegment('role-seg', 'role', role);
  modes.showRole(role);
  shown.refresh(false);
  roleControls();
}

/** The controls that depend on the role: Invert where the role can be inverted, the stiffness brush's slider. */
function roleControls() {
  /** @type {HTMLButtonElement} */ (document.getElementById('btn-invert')).disabled = !panel.enabled
    || !selection.invertible(painting.role);
  modes.enable(panel.enabled);
}

function setTool(/** @type {string} */ tool) {
  tools.toolChosen(tool);
  panel.setSegment('tool-seg', 'tool', tool);
}

function setBrushUnits(/** @type {string} 'screen' or 'world' */ units) {
  tools.unitsChosen(units);
  panel.setBrushRadius(units, painting.brush[units]);
}

function setGizmoMode(/** @type {'translate'|'rotate'} */ mode) {
  gizmo.setMode(mode);
  panel.setSegment('gizmo-seg', 'gizmo', mode);
}

// ------------------------------------------------------------------ start

panel.setEnabled(false);
panel.setConnection('connecting');
setTool('brush');
setRole('handle');
setGizmoMode('translate');
panel.setBrushRadius('screen', painting.brush.screen);
shown.updateList();
conn.connect();
keeper.offerSaved().catch((/** @type {Error} */ err) => panel.showStatus(`Saved sessions cannot be read: ${err.message || err}`, 'error'));
