// Per-vertex roles: region of interest, fixed anchors and handle groups.
//   roi:  Uint8Array, 1 = inside the painted region (an empty region means "whole mesh")
//   role: Int16Array, 0 = none, 1 = fixed anchor, 2 + g = handle group g

export const NONE = 0;
export const FIXED = 1;
export const HANDLE0 = 2;

export class Selection {
  constructor() {
    this.reset(0);
  }

  reset(n) {
    this.n = n;
    this.roi = new Uint8Array(n);
    this.role = new Int16Array(n);
    this.groups = [{ id: 1 }];
    this.nextGroupId = 2;
    this.activeGroup = 0;
    this.version = 0;
  }

  get roiCount() {
    let c = 0;
    for (let i = 0; i < this.n; i++) c += this.roi[i];
    return c;
  }

  /** Counts of roles: {roi, fixed, groups: [count per group]}. */
  counts() {
    const groups = new Array(this.groups.length).fill(0);
    let fixed = 0;
    let roi = 0;
    for (let i = 0; i < this.n; i++) {
      roi += this.roi[i];
      const r = this.role[i];
      if (r === FIXED) fixed++;
      else if (r >= HANDLE0) groups[r - HANDLE0]++;
    }
    return { roi, fixed, groups };
  }

  /** The value painted into `role` by a mode, or null for modes that only touch the ROI. */
  roleValue(mode) {
    if (mode === 'fixed') return FIXED;
    if (mode === 'handle') return HANDLE0 + this.activeGroup;
    if (mode === 'erase') return NONE;
    return null;
  }

  /** Paint `indices` (iterable of vertex ids) with a mode; subtract removes that mode instead. */
  paint(indices, mode, subtract = false) {
    let changed = false;
    const value = this.roleValue(mode);
    for (const i of indices) {
      if (mode === 'roi') {
        const v = subtract ? 0 : 1;
        if (this.roi[i] !== v) {
          this.roi[i] = v;
          changed = true;
        }
      } else if (mode === 'erase') {
        if (!subtract && (this.role[i] !== NONE || this.roi[i])) {
          this.role[i] = NONE;
          this.roi[i] = 0;
          changed = true;
        }
      } else if (subtract) {
        if (this.role[i] === value) {
          this.role[i] = NONE;
          changed = true;
        }
      } else if (this.role[i] !== value) {
        this.role[i] = value;
        changed = true;
      }
    }
    if (changed) this.version++;
    return changed;
  }

  clear(mode) {
    if (mode === 'roi') this.roi.fill(0);
    else if (mode === 'erase') {
      this.roi.fill(0);
      this.role.fill(NONE);
    } else {
      const value = this.roleValue(mode);
      for (let i = 0; i < this.n; i++) if (this.role[i] === value) this.role[i] = NONE;
    }
    this.version++;
  }

  /** Invert a role: ROI becomes its complement; anchors/handles swap with unassigned vertices. */
  invert(mode) {
    if (mode === 'erase') return false;
    if (mode === 'roi') {
      for (let i = 0; i < this.n; i++) this.roi[i] ^= 1;
    } else {
      const value = this.roleValue(mode);
      for (let i = 0; i < this.n; i++) {
        if (this.role[i] === value) this.role[i] = NONE;
        else if (this.role[i] === NONE) this.role[i] = value;
      }
    }
    this.version++;
    return true;
  }

  addGroup() {
    const counts = this.counts().groups;
    const empty = counts.findIndex((c) => c === 0);
    if (empty >= 0 && empty === this.groups.length - 1) {
      this.activeGroup = empty;
      return empty;
    }
    this.groups.push({ id: this.nextGroupId++ });
    this.activeGroup = this.groups.length - 1;
    this.version++;
    return this.activeGroup;
  }

  removeGroup(g) {
    for (let i = 0; i < this.n; i++) {
      const r = this.role[i];
      if (r === HANDLE0 + g) this.role[i] = NONE;
      else if (r > HANDLE0 + g) this.role[i] = r - 1;
    }
    this.groups.splice(g, 1);
    if (this.groups.length === 0) this.groups.push({ id: this.nextGroupId++ });
    this.activeGroup = Math.min(this.activeGroup, this.groups.length - 1);
    this.version++;
  }

  /** The mirror partner of handle group g (see mirror.js), or -1. */
  partnerOf(g) {
    const id = this.groups[g]?.partner;
    return id === undefined ? -1 : this.groups.findIndex((x) => x.id === id);
  }

  /** Make handle groups g and h each other's mirror partner (leaving their former partners unpaired). */
  pair(g, h) {
    for (const k of [g, h]) {
      const old = this.partnerOf(k);
      if (old >= 0) delete this.groups[old].partner;
    }
    this.groups[g].partner = this.groups[h].id;
    this.groups[h].partner = this.groups[g].id;
  }

  /** Vertex indices of handle group g. */
  groupIndices(g) {
    const out = [];
    const v = HANDLE0 + g;
    for (let i = 0; i < this.n; i++) if (this.role[i] === v) out.push(i);
    return out;
  }

  /**
   * The constraint set for the server. Empty groups are left out; `groupMap[k]` is the client group of
   * server group k.
   */
  toConstraints() {
    const fixed = [];
    const roi = [];
    const lists = this.groups.map(() => []);
    for (let i = 0; i < this.n; i++) {
      if (this.roi[i]) roi.push(i);
      const r = this.role[i];
      if (r === FIXED) fixed.push(i);
      else if (r >= HANDLE0) lists[r - HANDLE0].push(i);
    }
    const groupMap = [];
    const handleGroups = [];
    lists.forEach((list, g) => {
      if (list.length) {
        groupMap.push(g);
        handleGroups.push(list);
      }
    });
    return { roi: roi.length ? roi : null, fixed, handle_groups: handleGroups, groupMap };
  }

  /** Replace the selection by a constraint set ({roi, fixed, handle_groups}); bad indices are skipped. */
  fromConstraints(c) {
    const n = this.n;
    this.roi.fill(0);
    this.role.fill(NONE);
    const ok = (i) => Number.isInteger(i) && i >= 0 && i < n;
    for (const i of c.roi || []) if (ok(i)) this.roi[i] = 1;
    for (const i of c.fixed || []) if (ok(i)) this.role[i] = FIXED;
    const groups = c.handle_groups || [];
    groups.forEach((list, g) => {
      for (const i of list) if (ok(i)) this.role[i] = HANDLE0 + g;
    });
    this.groups = [];
    for (let g = 0; g < Math.max(1, groups.length); g++) this.groups.push({ id: this.nextGroupId++ });
    this.activeGroup = Math.min(this.activeGroup, this.groups.length - 1);
    this.version++;
  }
}

/** A canonical string of a constraint set, to compare what the server holds with the local selection. */
export function constraintsKey(c) {
  if (!c) return '';
  const roi = c.roi ? c.roi.join(',') : '*';
  const groups = (c.handle_groups || []).map((g) => g.join(',')).join('|');
  return `${roi};${(c.fixed || []).join(',')};${groups}`;
}
