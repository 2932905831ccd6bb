// Moving handle groups: the gizmo on the active group, the pivot, axes, snapping and typed-transform controls
// (transformui.js), and the drags they send. Every change of a group's transform (a pointer drag, a typed G/R +
// Enter, the panel's Apply) reaches the server through `onDrag` below, where mirror editing first moves the
// group's partner by the mirrored transform, so both travel in the same drag message.
import { HandleGizmo } from './gizmo.js';
import { FIXED } from './selection.js';
import { installTransformUi } from './transformui.js';

/** @typedef {import('./constraintsync.js').ConstraintSync} ConstraintSync */
/** @typedef {import('./selection.js').Selection} Selection */
/** @typedef {import('./stores/meshstore.js').MeshStore} MeshStore */
/** @typedef {import('./stores/historystore.js').HistoryStore} HistoryStore */

/** What a drag of a selection without anchors does, said as it starts. */
export const NO_ANCHORS_HINT = 'No anchors: the model moves rigidly; mark anchors (2) to hold part of it.';

/**
 * True when nothing holds the model against the dragged group: no anchors, no region of interest (outside it the
 * shape is held) and one handle group or point handle. The whole model then follows it rigidly.
 * @param {ConstraintSync} sync
 * @param {Selection} selection
 */
export function movesRigidly(sync, selection) {
  if (sync.groupMap.length !== 1 || selection.roiCount > 0) return false;
  const { role } = selection;
  for (let i = 0; i < role.length; i++) if (role[i] === FIXED) return false;
  return true;
}

/**
 * Why a drag cannot start while the server has refused the selection shown (`reason`: its words, or null).
 * @param {string|null} reason
 */
export function refusedDragText(reason) {
  const why = reason ? `: ${reason}` : '';
  return `Cannot drag: the server refused the current selection${why}. Change the selection, or undo.`;
}

/**
 * Create the gizmo and its controls. Call it before the selection tools and the orbit controls are created (the
 * gizmo and the pivot's click on the surface see pointer events first).
 * @param {object} opts
 * @param {MeshStore} opts.mesh the mesh shown (drags and typed transforms wait for it to be ready)
 * @param {HistoryStore} opts.history (a drag's end awaits its state)
 * @param {ConstraintSync} opts.sync whether the server holds the selection, and its group numbering
 * @param {import('./viewer.js').Viewer} opts.viewer
 * @param {Selection} opts.selection
 * @param {import('./mirror.js').MirrorEditing} opts.mirror
 * @param {import('./connection.js').Connection} opts.connection
 * @param {(text: string, kind?: string, ms?: number) => void} opts.status the status line
 * @param {() => void} opts.hush hides the status line
 * @param {(text: string) => void} opts.refused a request's error: a drag was refused
 * @param {() => void} opts.changed a pivot was placed or reset: something to save
 * @param {(text: string) => void} opts.hint a short note that hides no error
 * @returns {{gizmo: HandleGizmo, transformUi: ReturnType<typeof installTransformUi>}}
 */
export function installManipulation({
  mesh, history, sync, viewer, selection, mirror, connection, status, hush, refused, changed, hint,
}) {
  const gizmo = new HandleGizmo(viewer, {
    onDragStart: () => {
      if (!connection.open) {
        status('Not connected to the studio server: the handles can be moved again once it is back.', 'error');
        return false;
      }
      if (sync.selectionSynced()) {
        // the server holds the selection shown: a drag carries one transform per group of it
        sync.dragStarts();
        if (movesRigidly(sync, selection)) hint(NO_ANCHORS_HINT);
        return true;
      }
      if (!sync.pending) refused(refusedDragText(sync.refusal));
      else status('The new selection is still being set up; try again in a moment.', 'error', 3000);
      return false;
    },
    onDrag: () => {
      mirror.follow(gizmo, gizmo.group); // the partner group moves by the mirrored transform in the same message
      connection.drag(gizmo.transformsFor(sync.groupMap));
    },
    onDragEnd: () => {
      connection.endDrag();
      history.dragEnded();
    },
    onPivot: () => {
      mirror.followPivot(gizmo, gizmo.group); // the partner turns about the mirrored pivot
      changed();
    },
    onDraggingChanged: () => {},
  });
  const transformUi = installTransformUi({
    viewer, gizmo, canStart: () => mesh.ready, say: (text) => status(text, 'info', 4000), hush,
  });
  return { gizmo, transformUi };
}
