// Read-only view of the studio state on `window.__arap`, for automated browser tests and debugging.
import { computeNormals } from './normals.js';
import { picturePins } from './picturemode.js';
import { interpolate } from './timeline.js';

/**
 * The triangles of a mesh the viewer shows (it always draws them indexed).
 * @param {import('three').BufferGeometry} geometry
 */
const indexOf = (geometry) => /** @type {import('three').BufferAttribute} */ (geometry.index);

/**
 * Screen position of the gizmo, of points on its axes and on its rotate rings (CSS pixels relative to the canvas).
 * @param {import('./viewer.js').Viewer} viewer
 * @param {import('./gizmo.js').HandleGizmo} gizmo
 * @param {ReturnType<typeof import('./transformui.js').installTransformUi>} transformUi
 */
function gizmoInfo(viewer, gizmo, transformUi) {
  if (!gizmo.controls.object) return null;
  const c = gizmo.pivotWorld;
  const cam = viewer.camera;
  // TransformControls scales its helper to a constant screen size; its arrow pickers span 0..0.6 of that
  const scale = (cam.position.distanceTo(gizmo.pivot.position) * 1.9 * Math.tan((Math.PI * cam.fov) / 360) * gizmo.controls.size) / 4;
  const at = (/** @type {import('three').Vector3} */ d, /** @type {number} */ r) => viewer.project([c[0] + d.x * r, c[1] + d.y * r, c[2] + d.z * r]);
  /** @type {Record<string, number[]>} screen point of each axis (x, y, z) */
  const axes = {};
  /** @type {Record<string, number[][]>} screen points of each ring (x, y, z, e) */
  const rings = {};
  const eye = cam.position.clone().sub(gizmo.pivot.position).normalize();
  for (const name of ['x', 'y', 'z', 'e']) {
    const a = name === 'e' ? eye : gizmo.axisVector(name);
    if (name !== 'e') axes[name] = at(a, scale * 0.45);
    const radius = name === 'e' ? 0.75 : 0.5;
    // the ring about the axis (the view ring E about the line of sight), as 72 points (every 5°)
    const u = Math.abs(a.x) < 0.9 ? a.clone().set(1, 0, 0) : a.clone().set(0, 1, 0);
    u.sub(a.clone().multiplyScalar(u.dot(a))).normalize();
    const v = a.clone().cross(u);
    rings[name] = Array.from({ length: 72 }, (_, k) => {
      const phi = (k * Math.PI) / 36;
      return at(u.clone().multiplyScalar(Math.cos(phi)).addScaledVector(v, Math.sin(phi)), scale * radius);
    });
  }
  return {
    group: gizmo.group,
    centroid: gizmo.centroid,
    pivot: c,
    pivotPlaced: gizmo.pivotPlaced,
    placing: transformUi.picker.placing,
    screen: viewer.project(c),
    camera: cam.position.toArray(),
    axes,
    rings,
    mode: gizmo.controls.mode,
    space: gizmo.space,
    hover: gizmo.controls.axis,
    dragging: gizmo.dragging,
    snapping: gizmo.controls.snapping,
    gridStep: gizmo.gridStep,
    matrix: Array.from(gizmo.matrices[gizmo.group]?.elements ?? []),
    pivotMatrix: Array.from(gizmo.pivot.matrix.elements),
  };
}

/**
 * What the test hook reads.
 * @typedef {object} HookDeps
 * @property {import('./stores/meshstore.js').MeshStore} mesh
 * @property {import('./stores/historystore.js').HistoryStore} history
 * @property {import('./stores/paramstore.js').ParamStore} params
 * @property {import('./stores/diagnostics.js').Diagnostics} diagnostics
 * @property {import('./stores/toolstore.js').ToolStore} tools
 * @property {import('./constraintsync.js').ConstraintSync} sync
 * @property {import('./viewer.js').Viewer} viewer
 * @property {import('./livepose.js').LivePose} livePose
 * @property {import('./selection.js').Selection} selection
 * @property {import('./gizmo.js').HandleGizmo} gizmo
 * @property {import('./connection.js').Connection} conn
 * @property {import('./keeper.js').SessionKeeper} keeper
 * @property {import('./pointhandles.js').PointHandles} points
 * @property {import('./mirror.js').MirrorEditing} mirror
 * @property {ReturnType<typeof import('./transformui.js').installTransformUi>} transformUi
 * @property {import('./timeline.js').Timeline} timeline
 */

/**
 * Install `window.__arap`.
 * @param {HookDeps} deps
 */
export function installTestHook({
  mesh, history, params, diagnostics, tools, sync, viewer, livePose, selection, gizmo, conn, keeper, points, mirror, transformUi, timeline,
}) {
  const toPage = (/** @type {number[]} */ [x, y]) => {
    const r = viewer.canvas.getBoundingClientRect();
    return [x + r.left, y + r.top];
  };
  /** @type {any} */ (window).__arap = Object.freeze({
    get ready() {
      return mesh.ready;
    },
    get connected() {
      return conn.open;
    },
    get meshName() {
      return mesh.name;
    },
    get nVertices() {
      return viewer.nVertices;
    },
    /** The axis the view draws up: 'y' or 'z'. */
    get upAxis() {
      return viewer.upAxis;
    },
    /** The surface view: 'texture', 'colours' or 'plain'; `surfaces` lists those the mesh offers. */
    get surface() {
      return viewer.surface;
    },
    get surfaces() {
      return viewer.surfaces;
    },
    /** The texture image is decoded and drawn (true without one). */
    get textureReady() {
      return viewer.textureReady;
    },
    /** The layers the wireframe overlay is drawn in (a picture's pin depths; 0: over the whole mesh at once). */
    get wireLayers() {
      return viewer.wireLayers;
    },
    get nFaces() {
      return mesh.nFaces;
    },
    get repaired() {
      return mesh.repaired;
    },
    get lastSeq() {
      return mesh.lastSeq;
    },
    /** True while a request that changes the view is unanswered, or a shape received is not drawn yet. */
    get busy() {
      return history.busyFor !== null || sync.pending || history.awaitingState || conn.dragBusy || keeper.restore.busy
        || livePose.pending;
    },
    /** Vertices frames received and applied (the others were replaced by newer ones before being drawn). */
    get frames() {
      return { received: livePose.received, applied: livePose.applied };
    },
    get canUndo() {
      return history.canUndo;
    },
    get canRedo() {
      return history.canRedo;
    },
    get builtins() {
      return mesh.builtins.slice();
    },
    get params() {
      return { ...params.values };
    },
    get limits() {
      return { ...mesh.limits };
    },
    get errors() {
      return diagnostics.errors.map((e) => ({ ...e }));
    },
    /** Milliseconds of JavaScript per vertices frame applied (the newest 256; drawing excluded). */
    get frameMs() {
      return diagnostics.frameMs.slice();
    },
    get meshMs() {
      return diagnostics.meshMs;
    },
    /**
     * Wall-clock times (ms since the epoch) of the last upload: chosen, read, sent; then received, shown and drawn,
     * set by every mesh message (read them right after an upload).
     */
    get uploadAt() {
      return { ...diagnostics.uploadAt };
    },
    /**
     * Make the page slow at showing shapes: applying each vertices frame takes `ms` more milliseconds of
     * JavaScript (0: as fast as it is). For tests of how the page keeps up with frames that arrive faster.
     */
    slowDrawing: (/** @type {number} */ ms) => {
      const v = /** @type {any} */ (viewer);
      for (const name of ['updatePositions', 'updateSubset']) {
        const own = Object.getPrototypeOf(v)[name];
        if (ms > 0) {
          v[name] = (/** @type {unknown[]} */ ...args) => {
            const until = performance.now() + ms;
            while (performance.now() < until);
            return own.apply(v, args);
          };
        } else delete v[name];
      }
    },
    get messages() {
      return diagnostics.messages;
    },
    /** Autosave: idle (nothing waits to be written), saves (writes done), held (paused). */
    get autosave() {
      const a = keeper.autosave;
      return { idle: a.idle, saves: a.saves, held: a.held };
    },
    get restoring() {
      return keeper.restore.busy;
    },
    positions: () => Array.from(viewer.positions),
    /** Vertex colours (linear RGB, 3 per vertex) as drawn. */
    colors: () => (viewer.geometry ? Array.from(viewer.geometry.attributes.color.array) : []),
    faces: () => Array.from(viewer.geometry ? indexOf(viewer.geometry).array : []),
    normals: () => Array.from(viewer.geometry ? viewer.geometry.attributes.normal.array : []),
    /** Every vertex normal recomputed from the positions shown (what the normals kept per frame must equal). */
    recomputedNormals: () => {
      if (!viewer.geometry) return [];
      const out = new Float32Array(viewer.positions.length);
      computeNormals(viewer.positions, indexOf(viewer.geometry).array, out);
      return Array.from(out);
    },
    /** Bounding box [min, max] and sphere [centre, radius] the viewer keeps. */
    bounds: () => {
      const g = viewer.geometry;
      if (!g) return null;
      // the viewer computes both for every mesh it shows
      const box = /** @type {import('three').Box3} */ (g.boundingBox);
      const sphere = /** @type {import('three').Sphere} */ (g.boundingSphere);
      return { min: box.min.toArray(), max: box.max.toArray(), center: sphere.center.toArray(), radius: sphere.radius };
    },
    counts: () => selection.counts(),
    /** A picture's pins: their depths as last sent and the angles (degrees or null) the last state gave them. */
    picturePins: () => picturePins(),
    constraints: () => {
      const c = selection.toConstraints();
      return { roi: c.roi, fixed: c.fixed, handle_groups: c.handle_groups, stiffness: c.stiffness, points: c.points };
    },
    /** Per client group: {point, screen} of a point handle (page coordinates of its marker), null otherwise. */
    pointHandles: () => selection.groups.map((g, k) => (g.point
      ? { point: { ...g.point }, screen: toPage(/** @type {number[]} */ (points.screen()[k])) } : null)),
    get activeGroup() {
      return selection.activeGroup;
    },
    get role() {
      return tools.role;
    },
    /** Mirror editing: on, active (on with a plane), axis, plane, matched share, tolerance, ms, mirrorOf. */
    mirror: () => {
      const r = mirror.result;
      return {
        on: mirror.on,
        active: mirror.active,
        axis: mirror.axis,
        plane: r?.plane ?? null,
        matched: r?.matched ?? null,
        tolerance: r?.tolerance ?? null,
        ms: r?.ms ?? null,
        mirrorOf: r?.mirrorOf ? Array.from(r.mirrorOf) : null,
        visible: !!mirror.planeMesh?.visible,
      };
    },
    /** The mirror partner of each client handle group (-1: none). */
    partners: () => mirror.partners(),
    /** Page coordinates (CSS pixels) of a world point. */
    project: (/** @type {number[]} */ p) => toPage(viewer.project(p)),
    gizmo: () => {
      const g = gizmoInfo(viewer, gizmo, transformUi);
      if (!g) return null;
      const axes = Object.fromEntries(Object.entries(g.axes).map(([k, v]) => [k, toPage(v)]));
      const rings = Object.fromEntries(Object.entries(g.rings).map(([k, v]) => [k, v.map(toPage)]));
      return { ...g, screen: toPage(g.screen), axes, rings };
    },
    /** Every client group's transform (column-major 4×4), as the next drag would send it. */
    transforms: () => gizmo.matrices.map((m) => Array.from(m.elements)),
    /**
     * The keyframe timeline: its keyframes (time in ms, one column-major 4×4 per handle group, the vertices of the
     * shape the page keeps for it), the playhead,
     * playback and export state; `interpolate(keys, pivots, seconds)` is the page's interpolation rule.
     */
    get timeline() {
      return {
        keys: timeline.keys.map(({ shape, ...k }) => ({ ...k, transforms: k.transforms.map((m) => m.slice()),
          shapeVertices: shape ? shape.length / 3 : 0 })),
        pivots: timeline.pivots?.map((p) => p.slice()) ?? null,
        timeMs: timeline.timeMs,
        durationMs: timeline.durationMs,
        fps: timeline.fps,
        playing: timeline.playing,
        dragsSent: timeline.dragsSent,
        framesShown: timeline.framesShown,
        exporting: timeline.exporting,
        exportNote: timeline.exportNote,
        lastExport: timeline.lastExport ? { ...timeline.lastExport } : null,
      };
    },
    interpolate: (
      /** @type {import('./keyframes.js').Keyframe[]} */ keys, /** @type {number[][]} */ pivots, /** @type {number} */ seconds,
    ) => interpolate(keys, pivots, seconds),
    /** Move the playhead to `ms` as a scrub does (a drag there; `end`: then end the drag). */
    seek: (/** @type {number} */ ms, end = true) => (end ? timeline.goTo(ms) : timeline.seek(ms)),
    /** What the typed-transform line shows, or null when no transform is being typed. */
    get typing() {
      return transformUi.entry.active ? transformUi.entry.line.textContent : null;
    },
  });
}
