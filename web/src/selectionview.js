// Showing the selection: the colours of its roles on the model, the heat map's mask, the point handles' markers,
// the gizmo's groups, and the panel's list of groups and counts (with the guide's progress). A full refresh updates
// the panel at once; a quick one (during a brush stroke) at most every 100 ms.

/** How long a quick refresh may leave the panel's list of groups behind (ms). */
const LIST_DELAY_MS = 100;

/**
 * What showing the selection reads and tells.
 * @typedef {object} SelectionViewDeps
 * @property {import('./viewer.js').Viewer} viewer
 * @property {import('./selection.js').Selection} selection
 * @property {() => string} role the role painted
 * @property {import('./heatmap.js').HeatMap} heat
 * @property {import('./pointhandles.js').PointHandles} points
 * @property {import('./gizmo.js').HandleGizmo} gizmo
 * @property {import('./help.js').Help} help (its guide)
 * @property {import('./panel.js').Panel} panel
 * @property {() => void} changed something to save
 */

export class SelectionView {
  /** @param {SelectionViewDeps} deps */
  constructor(deps) {
    this.d = deps;
    this.listQueued = false;
  }

  /**
   * Show the selection; `full`: its panel list at once too (else within LIST_DELAY_MS).
   * @param {boolean} [full]
   */
  refresh(full = true) {
    const { viewer, selection, heat, points, gizmo } = this.d;
    viewer.updateColors(selection.roiCount ? selection.roi : null, selection.role, selection.stiff,
      this.d.role() === 'stiffness' ? 0.9 : 0.35);
    heat.paint();
    points.rebuild();
    gizmo.syncGroups(selection.groups.length);
    if (full) this.updateList();
    else this.scheduleList();
  }

  scheduleList() {
    if (this.listQueued) return;
    this.listQueued = true;
    setTimeout(() => {
      this.listQueued = false;
      this.updateList();
    }, LIST_DELAY_MS);
  }

  /** The panel's groups and counts, the guide's progress, and the gizmo on the active group. */
  updateList() {
    const { viewer, selection, points, gizmo } = this.d;
    this.d.changed();
    const counts = selection.counts();
    this.d.panel.setGroups(selection.groups, selection.activeGroup, counts, viewer.nVertices);
    this.d.help.guideProgress({ anchors: counts.fixed > 0, handle: counts.groups.some((c) => c > 0) });
    const anchor = points.anchor(selection.activeGroup);
    if (!gizmo.dragging) gizmo.attach(selection.activeGroup, anchor.indices, anchor.weights);
    points.refresh();
  }
}
