// Per-vertex roles: region of interest, fixed anchors and handle groups, the painted stiffness and point handles.
//   roi:   Uint8Array, 1 = inside the painted region (an empty region means "whole mesh")
//   role:  Int16Array, 0 = none, 1 = fixed anchor, 2 + g = handle group g
//   stiff: Float64Array, the cell weight of each vertex (1 = unpainted, Infinity = rigid)
// A handle group is either a set of vertices or one point handle: `groups[g].point` = {face, barycentric, weight}
// (weight null: a hard handle), with no vertices. `groups[g].partner` is the id of a vertex group's mirror partner
// (mirror.js); point handles have none.
import { CLIENT } from './protocol.js';
import { stiffnessFromJson, stiffnessKey, stiffnessToJson } from './stiffness.js';

/** @typedef {import('./protocol.js').SetConstraintsClientMessage} SetConstraintsClientMessage */
/** @typedef {{vertices: number[], value: number|"rigid"}[]} StiffnessJson */
/** A point handle: a point of a face given by barycentric coordinates; weight null: a hard handle.
 * @typedef {{face: number, barycentric: number[], weight: number|null}} PointHandle */
/** A point handle as the protocol sends it (no weight: hard).
 * @typedef {{face: number, barycentric: number[], weight?: number}} PointSpec */
/** @typedef {{id: number, partner?: number, point?: PointHandle}} HandleGroup */
/**
 * What Selection.copy keeps of a selection, for Selection.restored to put back.
 * @typedef {{role: Int16Array, roi: Uint8Array, stiff: Float64Array, activeGroup: number, groups: HandleGroup[]}}
 *   SelectionCopy
 */
/**
 * A constraint set as Selection.toConstraints gives it: `groupMap[k]` is the client group of server group k.
 * @typedef {object} Constraints
 * @property {number[]|null} roi
 * @property {number[]} fixed
 * @property {number[][]} handle_groups
 * @property {StiffnessJson|null} stiffness
 * @property {PointSpec[]} points
 * @property {number[]} groupMap
 */
/**
 * A constraint set as read from the server, a file or a snapshot (any field may be missing).
 * @typedef {object} ConstraintsLike
 * @property {number[]|null} [roi]
 * @property {number[]} [fixed]
 * @property {number[][]} [handle_groups]
 * @property {StiffnessJson|null} [stiffness]
 * @property {{face: number, barycentric: number[], weight?: number|null}[]|null} [points] (weight null: hard)
 */

export const NONE = 0;
export const FIXED = 1;
export const HANDLE0 = 2;

/** The value the stiffness brush paints until one is chosen. */
const STIFFNESS_BRUSH = 10;

export class Selection {
  // All set again by reset(), which the constructor calls. Only this class writes them: the other modules read them
  // and tell the selection what the user did through its methods (paint, groupChosen, stiffnessChosen …).
  #n = 0;
  /** @type {Uint8Array} */
  #roi = new Uint8Array(0);
  /** @type {Int16Array} */
  #role = new Int16Array(0);
  /** @type {Float64Array} */
  #stiff = new Float64Array(0);
  #stiffnessValue = STIFFNESS_BRUSH;
  /** @type {HandleGroup[]} */
  #groups = [];
  #nextGroupId = 1;
  #activeGroup = 0;
  #version = 0;

  constructor() {
    this.reset(0);
  }

  /** @param {number} n */
  reset(n) {
    this.#n = n;
    this.#roi = new Uint8Array(n);
    this.#role = new Int16Array(n);
    this.#stiff = new Float64Array(n).fill(1);
    this.#stiffnessValue = STIFFNESS_BRUSH;
    this.#groups = [{ id: 1 }];
    this.#nextGroupId = 2;
    this.#activeGroup = 0;
    this.#version = 0;
  }

  /** The number of vertices. */
  get n() {
    return this.#n;
  }

  /** @returns {Readonly<Uint8Array>} per vertex, 1 inside the painted region of interest */
  get roi() {
    return this.#roi;
  }

  /** @returns {Readonly<Int16Array>} per vertex: NONE, FIXED or HANDLE0 + its handle group */
  get role() {
    return this.#role;
  }

  /** @returns {Readonly<Float64Array>} per vertex, its painted stiffness (1 unpainted, Infinity rigid) */
  get stiff() {
    return this.#stiff;
  }

  /** The value the stiffness brush paints. */
  get stiffnessValue() {
    return this.#stiffnessValue;
  }

  /** @returns {readonly Readonly<HandleGroup>[]} the handle groups */
  get groups() {
    return this.#groups;
  }

  /** The handle group that painting a handle paints into and the gizmo moves. */
  get activeGroup() {
    return this.#activeGroup;
  }

  /** Counts the edits: it changes whenever the selection does. */
  get version() {
    return this.#version;
  }

  get roiCount() {
    let c = 0;
    for (let i = 0; i < this.#n; i++) c += this.#roi[i];
    return c;
  }

  /**
   * The user chose handle group g.
   * @param {number} g
   */
  groupChosen(g) {
    this.#activeGroup = g;
  }

  /**
   * The user chose the value the stiffness brush paints.
   * @param {number} value (Infinity: rigid)
   */
  stiffnessChosen(value) {
    this.#stiffnessValue = value;
  }

  /** Counts of roles: {roi, fixed, groups: [count per group]}. */
  counts() {
    const groups = new Array(this.#groups.length).fill(0);
    let fixed = 0;
    let roi = 0;
    for (let i = 0; i < this.#n; i++) {
      roi += this.#roi[i];
      const r = this.#role[i];
      if (r === FIXED) fixed++;
      else if (r >= HANDLE0) groups[r - HANDLE0]++;
    }
    return { roi, fixed, groups };
  }

  /**
   * The value painted into `role` by a mode, or null for modes that only touch the ROI.
   * @param {string} mode
   * @param {number} [group] the handle group that mode 'handle' paints (the active one by default)
   * @returns {number|null}
   */
  roleValue(mode, group = this.#activeGroup) {
    if (mode === 'fixed') return FIXED;
    if (mode === 'handle') return HANDLE0 + group;
    if (mode === 'erase') return NONE;
    return null;
  }

  /** True when the active group is a point handle. */
  get activeIsPoint() {
    return !!this.#groups[this.#activeGroup]?.point;
  }

  /**
   * Paint `indices` (iterable of vertex ids) with a mode; subtract removes that mode instead.
   * @param {Iterable<number>} indices
   * @param {string} mode
   * @param {boolean} [subtract]
   * @param {number} [group] the handle group that mode 'handle' paints (the active one by default)
   */
  paint(indices, mode, subtract = false, group = this.#activeGroup) {
    let changed = false;
    if (mode === 'handle' && this.#groups[group]?.point) group = this.addGroup(); // a point handle has no vertices
    if (mode === 'point') return false;
    const value = this.roleValue(mode, group);
    const stiffness = subtract ? 1 : this.#stiffnessValue;
    for (const i of indices) {
      if (mode === 'stiffness') {
        if (this.#stiff[i] !== stiffness) {
          this.#stiff[i] = stiffness;
          changed = true;
        }
      } else if (mode === 'roi') {
        const v = subtract ? 0 : 1;
        if (this.#roi[i] !== v) {
          this.#roi[i] = v;
          changed = true;
        }
      } else if (mode === 'erase') {
        if (!subtract && (this.#role[i] !== NONE || this.#roi[i])) {
          this.#role[i] = NONE;
          this.#roi[i] = 0;
          changed = true;
        }
      } else if (subtract) {
        if (this.#role[i] === value) {
          this.#role[i] = NONE;
          changed = true;
        }
      } else if (this.#role[i] !== value) {
        this.#role[i] = value ?? NONE;
        changed = true;
      }
    }
    if (changed) this.#version++;
    return changed;
  }

  /**
   * Take a role off every vertex (mode 'erase': every role, the point handles and the stiffness).
   * @param {string} mode
   * @param {number} [group] the handle group that mode 'handle' clears (the active one by default)
   */
  clear(mode, group = this.#activeGroup) {
    if (mode === 'roi') this.#roi.fill(0);
    else if (mode === 'stiffness') this.#stiff.fill(1);
    else if (mode === 'point') {
      for (let g = this.#groups.length - 1; g >= 0; g--) if (this.#groups[g].point) this.removeGroup(g);
    } else if (mode === 'erase') {
      this.#roi.fill(0);
      this.#role.fill(NONE);
      this.#stiff.fill(1);
      this.#groups = this.#groups.filter((g) => !g.point);
      if (!this.#groups.length) this.#groups.push({ id: this.#nextGroupId++ });
      this.#activeGroup = Math.min(this.#activeGroup, this.#groups.length - 1);
    } else {
      const value = this.roleValue(mode, group);
      for (let i = 0; i < this.#n; i++) if (this.#role[i] === value) this.#role[i] = NONE;
    }
    this.#version++;
  }

  /**
   * True when `invert(mode)` can do something for this mode.
   * @param {string} mode
   */
  invertible(mode) {
    return mode !== 'erase' && mode !== 'stiffness' && mode !== 'point';
  }

  /**
   * Invert a role: ROI becomes its complement; anchors/handles swap with unassigned vertices.
   * @param {string} mode
   */
  invert(mode) {
    if (!this.invertible(mode)) return false;
    if (mode === 'roi') {
      for (let i = 0; i < this.#n; i++) this.#roi[i] ^= 1;
    } else {
      const value = this.roleValue(mode);
      for (let i = 0; i < this.#n; i++) {
        if (this.#role[i] === value) this.#role[i] = NONE;
        else if (this.#role[i] === NONE) this.#role[i] = value ?? NONE;
      }
    }
    this.#version++;
    return true;
  }

  addGroup() {
    const counts = this.counts().groups;
    const empty = counts.findIndex((c, g) => c === 0 && !this.#groups[g].point);
    if (empty >= 0 && empty === this.#groups.length - 1) {
      this.#activeGroup = empty;
      return empty;
    }
    this.#groups.push({ id: this.#nextGroupId++ });
    this.#activeGroup = this.#groups.length - 1;
    this.#version++;
    return this.#activeGroup;
  }

  /** @param {number} g */
  removeGroup(g) {
    for (let i = 0; i < this.#n; i++) {
      const r = this.#role[i];
      if (r === HANDLE0 + g) this.#role[i] = NONE;
      else if (r > HANDLE0 + g) this.#role[i] = r - 1;
    }
    this.#groups.splice(g, 1);
    if (this.#groups.length === 0) this.#groups.push({ id: this.#nextGroupId++ });
    this.#activeGroup = Math.min(this.#activeGroup, this.#groups.length - 1);
    this.#version++;
  }

  /**
   * Add a point handle ({face, barycentric, weight}) as a new group and make it the active one.
   * @param {PointHandle} point
   */
  addPoint(point) {
    const last = this.#groups.length - 1;
    const counts = this.counts().groups;
    if (counts[last] === 0 && !this.#groups[last].point) this.#groups.pop(); // an empty vertex group gives way
    this.#groups.push({ id: this.#nextGroupId++, point });
    this.#activeGroup = this.#groups.length - 1;
    this.#version++;
    return this.#activeGroup;
  }

  /**
   * The mirror partner of handle group g (see mirror.js), or -1.
   * @param {number} g
   */
  partnerOf(g) {
    const id = this.#groups[g]?.partner;
    return id === undefined ? -1 : this.#groups.findIndex((x) => x.id === id);
  }

  /**
   * Make handle groups g and h each other's mirror partner (leaving their former partners unpaired). Point handles
   * are never paired: false (and nothing changes) when g or h is one.
   * @param {number} g
   * @param {number} h
   */
  pair(g, h) {
    if (this.#groups[g]?.point || this.#groups[h]?.point) return false;
    for (const k of [g, h]) {
      const old = this.partnerOf(k);
      if (old >= 0) delete this.#groups[old].partner;
    }
    this.#groups[g].partner = this.#groups[h].id;
    this.#groups[h].partner = this.#groups[g].id;
    return true;
  }

  /**
   * Mirror editing needs a partner for vertex group g: a new empty vertex group, paired with g (see pair); its index.
   * The active group stays.
   * @param {number} g
   */
  partnerAdded(g) {
    this.#groups.push({ id: this.#nextGroupId++ });
    const p = this.#groups.length - 1;
    this.pair(g, p);
    this.#version++;
    return p;
  }

  /**
   * A copy of the painted roles, region and stiffness, the handle groups and the active group, for `restored`.
   * @returns {SelectionCopy}
   */
  copy() {
    return {
      role: this.#role.slice(), roi: this.#roi.slice(), stiff: this.#stiff.slice(), activeGroup: this.#activeGroup,
      groups: copyGroups(this.#groups),
    };
  }

  /**
   * The selection goes back to what `copy` gave (taken with the same number of vertices).
   * @param {SelectionCopy} saved
   */
  restored(saved) {
    this.#role.set(saved.role);
    this.#roi.set(saved.roi);
    this.#stiff.set(saved.stiff);
    this.#groups = copyGroups(saved.groups);
    this.#activeGroup = saved.activeGroup;
    this.#version++;
  }

  /**
   * Vertex indices of handle group g.
   * @param {number} g
   */
  groupIndices(g) {
    const out = [];
    const v = HANDLE0 + g;
    for (let i = 0; i < this.#n; i++) if (this.#role[i] === v) out.push(i);
    return out;
  }

  /**
   * The constraint set for the server. Empty groups are left out; `groupMap[k]` is the client group of
   * server group k.
   * @returns {Constraints}
   */
  toConstraints() {
    const stiffness = stiffnessToJson(this.#stiff);
    /** @type {number[]} */
    const fixed = [];
    /** @type {number[]} */
    const roi = [];
    /** @type {number[][]} */
    const lists = this.#groups.map(() => []);
    for (let i = 0; i < this.#n; i++) {
      if (this.#roi[i]) roi.push(i);
      const r = this.#role[i];
      if (r === FIXED) fixed.push(i);
      else if (r >= HANDLE0) lists[r - HANDLE0].push(i);
    }
    /** @type {number[]} */
    const groupMap = [];
    /** @type {number[][]} */
    const handleGroups = [];
    lists.forEach((list, g) => {
      if (list.length && !this.#groups[g].point) {
        groupMap.push(g);
        handleGroups.push(list);
      }
    });
    /** @type {PointSpec[]} */
    const points = [];
    this.#groups.forEach((group, g) => {
      if (!group.point) return;
      const { face, barycentric, weight } = group.point;
      groupMap.push(g);
      points.push(weight === null || weight === undefined ? { face, barycentric } : { face, barycentric, weight });
    });
    return { roi: roi.length ? roi : null, fixed, handle_groups: handleGroups, stiffness, points, groupMap };
  }

  /**
   * Replace the selection by a constraint set ({roi, fixed, handle_groups, stiffness?, points?}); bad indices are
   * skipped. Point handles become groups after the vertex groups; `groupPoints` (one entry per group of
   * `handle_groups`, null for a vertex group) puts saved point handles back in their places instead.
   * @param {ConstraintsLike} c
   * @param {(PointHandle|null|undefined)[]|null} [groupPoints]
   */
  fromConstraints(c, groupPoints = null) {
    const n = this.#n;
    this.#roi.fill(0);
    this.#role.fill(NONE);
    this.#stiff = stiffnessFromJson(c.stiffness, n);
    const ok = (/** @type {number} */ i) => Number.isInteger(i) && i >= 0 && i < n;
    for (const i of c.roi || []) if (ok(i)) this.#roi[i] = 1;
    for (const i of c.fixed || []) if (ok(i)) this.#role[i] = FIXED;
    const groups = c.handle_groups || [];
    groups.forEach((list, g) => {
      for (const i of list) if (ok(i)) this.#role[i] = HANDLE0 + g;
    });
    this.#groups = [];
    for (let g = 0; g < groups.length; g++) {
      const point = groupPoints?.[g];
      this.#groups.push(point ? { id: this.#nextGroupId++, point: { ...point } } : { id: this.#nextGroupId++ });
    }
    for (const p of c.points || []) {
      const point = { face: p.face, barycentric: p.barycentric.slice(), weight: p.weight ?? null };
      this.#groups.push({ id: this.#nextGroupId++, point });
    }
    if (!this.#groups.length) this.#groups.push({ id: this.#nextGroupId++ });
    this.#activeGroup = Math.min(this.#activeGroup, this.#groups.length - 1);
    this.#version++;
  }
}

/**
 * Copies of handle groups (a point handle's point copied too).
 * @param {readonly HandleGroup[]} groups
 * @returns {HandleGroup[]}
 */
function copyGroups(groups) {
  return groups.map((g) => ({ ...g, ...(g.point ? { point: { ...g.point } } : {}) }));
}

/**
 * The set_constraints message of a constraint set (Selection.toConstraints): `targets` (a Map from handle vertex to
 * [x, y, z]) moves the handles there, `pointTargets` (one [x, y, z] or null per point handle) the point handles.
 * `targets` holds every handle vertex (readConstraintsFile checks it).
 * @param {Constraints} c
 * @param {Map<number, number[]>|null} [targets]
 * @param {(number[]|null|undefined)[]|null} [pointTargets]
 * @returns {SetConstraintsClientMessage}
 */
export function constraintsMessage(c, targets = null, pointTargets = null) {
  /** @type {SetConstraintsClientMessage} */
  const msg = { type: CLIENT.SET_CONSTRAINTS, roi: c.roi, fixed: c.fixed, handle_groups: c.handle_groups };
  if (targets) msg.targets = c.handle_groups.flat().map((i) => /** @type {number[]} */ (targets.get(i)));
  if (c.stiffness) msg.stiffness = c.stiffness;
  if (c.points.length) {
    msg.points = c.points.map((p, k) => {
      const target = pointTargets?.[k];
      return target ? { ...p, target } : p;
    });
  }
  return msg;
}

/**
 * A canonical string of a constraint set, to compare what the server holds with the local selection.
 * @param {ConstraintsLike|null|undefined} c
 */
export function constraintsKey(c) {
  if (!c) return '';
  const roi = c.roi ? c.roi.join(',') : '*';
  const groups = (c.handle_groups || []).map((g) => g.join(',')).join('|');
  const points = (c.points || []).map((p) => `${p.face}:${p.barycentric.join(',')}:${p.weight ?? 'hard'}`).join('|');
  return `${roi};${(c.fixed || []).join(',')};${groups};${points};${stiffnessKey(c.stiffness)}`;
}
