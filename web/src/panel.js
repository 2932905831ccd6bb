// The side panel's controls: model choice, tools, roles and handle groups, solver parameters, export, view
// options, each bound to a studio action (main.js supplies them once every piece is built: bind), and the panel's
// answers to what happens to the connection. What the panel only displays (status bar, connection, statistics,
// settling) is in readouts.js, whose class this one extends, so that the studio still talks to one panel object.
import { REFERENCED_EXTENSIONS } from './files.js';
import { installPictureControls, pictureShown, warpShown } from './picturemode.js';
import { EXPORT_FORMATS, PARAMS, UPLOAD_EXTENSIONS } from './protocol.js';
import { fmtInt, PanelReadouts } from './readouts.js';
import { cssColor, FIXED_COLOR, groupColor } from './rolecolors.js';

export { countOf, settleText } from './readouts.js';

/**
 * A panel element by id (form controls of several kinds: typed loosely).
 * @param {string} id
 * @returns {any}
 */
const $ = (id) => document.getElementById(id);

/** The control an event came from. @param {Event} e @returns {any} */
const source = (/** @type {Event} */ e) => e.target;

/**
 * Fill a drop-down with the choices of a solver parameter, labelled as the protocol names them.
 * @param {HTMLSelectElement} select
 * @param {{choices: readonly string[], labels: Object<string, string>, default: string}} param
 */
function fillChoices(select, param) {
  select.innerHTML = '';
  for (const value of param.choices) {
    const o = document.createElement('option');
    o.value = value;
    o.textContent = param.labels[value] ?? value;
    select.appendChild(o);
  }
  select.value = param.default;
}

/**
 * What the panel's controls do (main.js supplies them).
 * @typedef {object} PanelActions
 * @property {(msg: import('./protocol.js').ClientMessage) => boolean} send
 * @property {(name: string) => void} loadBuiltin
 * @property {(files: File[]) => void} uploadFile a mesh file, or one with the files it names
 * @property {(file: File) => void} loadConstraintsFile
 * @property {(tool: string) => void} setTool
 * @property {(role: string) => void} setRole
 * @property {() => number|null} activePin the active pin's number among the point handles (null: none active)
 * @property {(mode: 'translate'|'rotate') => void} setGizmoMode
 * @property {(mode: 'texture'|'colours'|'plain') => void} setSurface
 * @property {(value: number) => void} setBrushRadius
 * @property {(units: string) => void} setBrushUnits
 * @property {(on: boolean) => void} setFrontOnly
 * @property {() => void} clearRole
 * @property {() => void} invertRole
 * @property {() => void} clearAll
 * @property {() => void} newGroup
 * @property {(g: number) => void} removeGroup
 * @property {(g: number) => void} selectGroup
 * @property {() => void} undo
 * @property {() => void} redo
 * @property {(params: Omit<import('./protocol.js').SetParamsClientMessage, 'type'>) => void} setParams
 * @property {() => void} saveConstraints
 * @property {(on: boolean) => void} setFlatShading
 * @property {(on: boolean) => void} setWireframe
 * @property {(axis: 'y'|'z') => void} setUpAxis
 * @property {() => void} fit
 * @property {() => void} reconnect
 */

/** The actions of a panel whose controls are not bound yet: none of them is called before bind. */
const UNBOUND = /** @type {PanelActions} */ ({});

export class Panel extends PanelReadouts {
  /**
   * The panel's readouts work at once; its controls act once bound to the studio's actions (bind).
   */
  constructor() {
    super();
    /** @type {PanelActions} the actions of the controls (see main.js) */
    this.actions = UNBOUND;
    this.enabled = true; // the controls take input (not while the server is away)
    /** @type {import('./protocol.js').PreparingServerMessage|undefined} the server's last word on its compilation */
    this.lastPreparing = undefined;
  }

  /**
   * Bind the controls to the studio's actions (once, when the pieces they act on are built).
   * @param {PanelActions} actions callbacks invoked by the controls (see main.js)
   */
  bind(actions) {
    this.actions = actions;

    $('builtin-select').addEventListener('change', (/** @type {Event} */ e) => actions.loadBuiltin(source(e).value));
    const fileInput = /** @type {HTMLInputElement} */ ($('file-input'));
    fileInput.accept = [...UPLOAD_EXTENSIONS, ...REFERENCED_EXTENSIONS].join(',');
    fileInput.multiple = true; // a mesh file with its MTL file, textures and buffers
    $('btn-open').addEventListener('click', () => $('file-input').click());
    $('file-input').addEventListener('change', (/** @type {Event} */ e) => {
      const files = Array.from(source(e).files || []);
      source(e).value = '';
      if (files.length) actions.uploadFile(files);
    });
    this._segment('tool-seg', 'tool', (v) => actions.setTool(v));
    this._segment('role-seg', 'role', (v) => actions.setRole(v));
    this._segment('gizmo-seg', 'gizmo', (v) => actions.setGizmoMode(/** @type {'translate'|'rotate'} */ (v)));
    this._segment('surface-seg', 'surface', (v) => actions.setSurface(/** @type {'texture'|'colours'|'plain'} */ (v)));

    const radius = $('brush-radius');
    radius.addEventListener('input', () => actions.setBrushRadius(Number(radius.value)));
    $('brush-units').addEventListener('change', (/** @type {Event} */ e) => actions.setBrushUnits(source(e).value));
    $('front-only').addEventListener('change', (/** @type {Event} */ e) => actions.setFrontOnly(source(e).checked));
    $('btn-clear').addEventListener('click', () => actions.clearRole());
    $('btn-invert').addEventListener('click', () => actions.invertRole());
    $('btn-clear-all').addEventListener('click', () => actions.clearAll());
    $('btn-new-group').addEventListener('click', () => actions.newGroup());

    $('btn-undo').addEventListener('click', () => actions.undo());
    $('btn-redo').addEventListener('click', () => actions.redo());
    $('btn-reset').addEventListener('click', () => actions.send({ type: 'reset' }));
    $('btn-apply').addEventListener('click', () => actions.send({ type: 'apply' }));

    const it = $('iterations');
    it.min = String(PARAMS.iterations.min);
    it.max = String(PARAMS.iterations.max);
    it.value = String(PARAMS.iterations.default);
    $('iterations-val').textContent = it.value;
    fillChoices($('energy'), PARAMS.energy);
    fillChoices($('weights'), PARAMS.weights);
    fillChoices($('loose'), PARAMS.loose);
    const alpha = $('alpha');
    alpha.min = String(PARAMS.alpha.min);
    alpha.max = String(PARAMS.alpha.max);
    alpha.step = String(PARAMS.alpha.step);
    alpha.value = String(PARAMS.alpha.default);
    $('alpha-val').textContent = alpha.value;
    alpha.addEventListener('input', () => ($('alpha-val').textContent = alpha.value));
    alpha.addEventListener('change', () => actions.setParams({ alpha: Number(alpha.value) }));
    it.addEventListener('input', () => ($('iterations-val').textContent = it.value));
    it.addEventListener('change', () => actions.setParams({ iterations: Number(it.value) }));
    $('energy').addEventListener('change', (/** @type {Event} */ e) => actions.setParams({ energy: source(e).value }));
    $('weights').addEventListener('change', (/** @type {Event} */ e) => actions.setParams({ weights: source(e).value }));
    $('loose').addEventListener('change', (/** @type {Event} */ e) => actions.setParams({ loose: source(e).value }));
    installPictureControls(actions);

    for (const format of EXPORT_FORMATS) {
      const b = document.createElement('button');
      b.id = `btn-export-${format}`;
      b.dataset.testid = `export-${format}`;
      b.textContent = `Export ${format.toUpperCase()}`;
      b.addEventListener('click', () => actions.send({
        type: 'export', format: /** @type {import('./protocol.js').ExportClientMessage['format']} */ (format) }));
      $('export-buttons').appendChild(b);
    }
    $('btn-save-constraints').addEventListener('click', () => actions.saveConstraints());
    $('btn-load-constraints').addEventListener('click', () => $('constraints-input').click());
    $('constraints-input').addEventListener('change', (/** @type {Event} */ e) => {
      const f = source(e).files?.[0];
      source(e).value = '';
      if (f) actions.loadConstraintsFile(f);
    });

    $('flat-shading').addEventListener('change', (/** @type {Event} */ e) => actions.setFlatShading(source(e).checked));
    $('wireframe').addEventListener('change', (/** @type {Event} */ e) => actions.setWireframe(source(e).checked));
    $('up-axis').addEventListener('change', (/** @type {Event} */ e) => actions.setUpAxis(
      source(e).value === 'z' ? 'z' : 'y'));
    $('btn-fit').addEventListener('click', () => actions.fit());
    $('btn-reconnect').addEventListener('click', () => actions.reconnect());
    $('status-close').addEventListener('click', () => this.hideStatus());
  }

  /**
   * @param {string} id
   * @param {string} key the buttons' data attribute
   * @param {(value: string) => void} onPick
   */
  _segment(id, key, onPick) {
    const el = $(id);
    el.addEventListener('click', (/** @type {Event} */ e) => {
      const b = source(e).closest('button');
      if (b && !b.disabled) onPick(b.dataset[key]);
    });
  }

  /**
   * @param {string} id
   * @param {string} key
   * @param {string} value
   */
  setSegment(id, key, value) {
    for (const b of $(id).querySelectorAll('button')) b.classList.toggle('active', b.dataset[key] === value);
  }

  /**
   * @param {string} units 'world' or 'screen'
   * @param {number} value
   */
  setBrushRadius(units, value) {
    const r = $('brush-radius');
    if (units === 'world') {
      r.min = '1';
      r.max = '25';
      r.value = String(value);
      $('brush-radius-val').textContent = `${value}%`;
      r.title = 'Brush radius, percent of the bounding-box diagonal';
    } else {
      r.min = '2';
      r.max = '120';
      r.value = String(value);
      $('brush-radius-val').textContent = `${value} px`;
      r.title = 'Brush radius on screen, pixels';
    }
  }

  /**
   * @param {readonly string[]} names
   * @param {string|null} current
   * @param {boolean} builtin `current` is the built-in model of that name (not a file named like it)
   */
  setBuiltins(names, current, builtin) {
    const sel = $('builtin-select');
    sel.innerHTML = '';
    const head = document.createElement('option');
    head.value = '';
    head.textContent = 'Built-in model…';
    head.disabled = true;
    sel.appendChild(head);
    for (const n of names) {
      const o = document.createElement('option');
      o.value = n;
      o.textContent = n;
      sel.appendChild(o);
    }
    this.setCurrentModel(current, builtin);
  }

  /**
   * Show the model loaded: a built-in one selected in the list, any other (a file, even one named like a built-in
   * model) by its name at the list's head.
   * @param {string|null} name
   * @param {boolean} builtin the model is the built-in one of that name (the mesh message's `builtin`)
   */
  setCurrentModel(name, builtin) {
    const sel = /** @type {HTMLSelectElement} */ ($('builtin-select'));
    const known = builtin && Array.from(sel.options).some((o) => o.value === name && name);
    const head = sel.options[0];
    if (head && head.value === '') head.textContent = !known && name ? `${name} (file)` : 'Built-in model…';
    sel.value = known ? /** @type {string} known */ (name) : '';
  }

  /** @param {string} text */
  setMeshInfo(text) {
    $('mesh-info').textContent = text;
  }

  /**
   * A new mesh arrived (the server's mesh message): its name and counts, and the repairs made loading it.
   * @param {import('./protocol.js').MeshServerMessage} msg
   */
  meshLoaded(msg) {
    const n = (/** @type {number} */ x) => x.toLocaleString('en-US');
    this.setCurrentModel(msg.name, !!msg.builtin);
    const tets = msg.n_tetrahedra ? `, ${n(msg.n_tetrahedra)} tetrahedra` : '';
    this.setMeshInfo(`${msg.name}: ${n(msg.n_vertices)} vertices, ${n(msg.n_faces)} faces${tets}`);
    this.setStats({ n_vertices: msg.n_vertices, n_faces: msg.n_faces, n_tetrahedra: msg.n_tetrahedra || 0, ups: NaN,
      latency_ms: null, ms_per_iteration: null });
    this.resetSettle(); // the server says how the new mesh's shape settles
    pictureShown(msg);
    const report = Array.isArray(msg.report) ? msg.report : msg.report ? [String(msg.report)] : [];
    if (report.length) this.showStatus(`Loaded ${msg.name}. Repairs: ${report.join('; ')}`, 'info', 8000);
    else this.hideStatus();
  }

  /**
   * The Surface control: one button per view the mesh offers (texture, colours, plain), the current one active;
   * hidden for a plain mesh.
   * @param {string[]} available
   * @param {string} current
   */
  setSurfaces(available, current) {
    $('surface-row').hidden = available.length < 2;
    for (const b of $('surface-seg').querySelectorAll('button')) b.hidden = !available.includes(b.dataset.surface);
    this.setSegment('surface-seg', 'surface', current);
  }

  /** @param {Partial<import('./stores/paramstore.js').SolverParams>|null|undefined} p */
  setParams(p) {
    if (!p) return;
    if (Number.isFinite(p.iterations)) {
      const v = Math.max(PARAMS.iterations.min, Math.min(PARAMS.iterations.max, /** @type {number} finite */ (p.iterations)));
      $('iterations').value = String(v);
      $('iterations-val').textContent = String(p.iterations);
    }
    if (p.energy) {
      $('energy').value = p.energy;
      $('alpha-row').hidden = p.energy !== 'smooth_rotations';
    }
    if (Number.isFinite(p.alpha)) {
      $('alpha').value = String(p.alpha);
      $('alpha-val').textContent = String(p.alpha);
    }
    if (p.weights) $('weights').value = p.weights;
    if (p.loose) $('loose').value = p.loose;
    warpShown(p);
  }

  /**
   * @param {boolean} canUndo
   * @param {boolean} canRedo
   */
  setHistory(canUndo, canRedo) {
    $('btn-undo').disabled = !canUndo;
    $('btn-redo').disabled = !canRedo;
  }

  /** @param {boolean} on */
  setEnabled(on) {
    this.enabled = on;
    for (const b of document.querySelectorAll('#panel button, #panel select, #panel input')) {
      if (!(b instanceof HTMLButtonElement || b instanceof HTMLSelectElement || b instanceof HTMLInputElement)) continue;
      if (b.id === 'btn-reconnect' || b.id === 'btn-help') continue;
      b.disabled = !on;
    }
  }

  /** The connection went away: the controls wait for it (the work is kept). */
  connectionLost() {
    this.setEnabled(false);
    this.setBusy(null);
    this.settleUnknown();
    this.showStatus('Lost the connection to the studio server; reconnecting… Your work is kept and comes back ' +
      'when the server does.', 'error', 0, 'connection');
  }

  /**
   * The server is full and refused this tab (`reason`: its words); it is tried again after `delayMs`. `keptWork`:
   * this page holds work from an earlier connection, put back once the server lets it in.
   * @param {string} reason
   * @param {number} delayMs
   * @param {boolean} keptWork
   */
  serverFull(reason, delayMs, keptWork) {
    this.setEnabled(false);
    this.setBusy(null);
    this.settleUnknown();
    this.setConnection('full', { attempt: 0, delayMs });
    const why = reason ? ` (server: “${reason}”)` : '';
    const kept = keptWork ? ' Your work is kept and comes back once this tab gets in.' : '';
    this.showStatus(`The studio server is full and did not let this tab in${why}. Close another studio tab, then `
      + `press Reconnect; this page also tries again every ${Math.round(delayMs / 1000)} s.${kept}`, 'error', 0,
    'connection');
  }

  /**
   * Connected, but the server has not greeted this tab yet: it is preparing the solver (compiling, first run).
   * @param {import('./protocol.js').PreparingServerMessage} [progress] how far the compilation is, when the server
   *   said so
   */
  preparingSolver(progress) {
    this.setConnection('preparing');
    if (progress) this.lastPreparing = progress;
    else progress = this.lastPreparing; // the late-welcome notice keeps the progress already shown
    let how = 'the first run after an install compiles it.';
    if (progress) {
      const now = progress.kernel ? ` (${progress.compiling ? 'compiling' : 'compiled'} ${progress.kernel})` : '';
      how = `the first run after an install compiles it: ${progress.done} of ${progress.total} kernels ready${now}, `
        + `${Math.round(progress.seconds)} s so far.`;
    }
    this.showStatus(`Connected. The server is preparing the solver: ${how} Editing starts as soon as the kernels `
      + 'it needs first are ready.', 'info', 0, 'preparing');
  }

  /**
   * The server speaks another protocol version (a page left open across an upgrade): nothing is sent.
   * @param {number} ours
   * @param {number} theirs
   */
  protocolMismatch(ours, theirs) {
    this.setEnabled(false);
    this.showStatus(`This page speaks version ${ours} of the studio protocol and the server version ${theirs}: `
      + 'reload the page.', 'error', 0, 'connection');
  }

  /**
   * groups: [{id, partner?}] (partner: the id of its mirror partner), active: index, roi/fixed counts.
   * @param {readonly Readonly<import('./selection.js').HandleGroup>[]} groups
   * @param {number} active
   * @param {ReturnType<import('./selection.js').Selection['counts']>} counts
   * @param {number} nVertices
   */
  setGroups(groups, active, counts, nVertices) {
    const ul = $('group-list');
    ul.innerHTML = '';
    groups.forEach((g, k) => {
      const li = document.createElement('li');
      li.dataset.testid = `group-${k}`;
      li.classList.toggle('active', k === active);
      const sw = document.createElement('span');
      sw.className = 'swatch';
      sw.style.background = cssColor(groupColor(k));
      const name = document.createElement('span');
      name.className = 'name';
      const partner = groups.findIndex((h) => g.partner !== undefined && h.id === g.partner);
      const label = g.point ? `Point ${k + 1}` : `Group ${k + 1}`;
      name.textContent = partner >= 0 ? `${label} ⇄ ${partner + 1}` : label;
      if (partner >= 0) name.title = `Mirror partner of group ${partner + 1}`;
      const count = document.createElement('span');
      count.className = 'count';
      const w = g.point?.weight;
      count.textContent = g.point ? (w ? `soft ${w}` : 'hard') : `${fmtInt(counts.groups[k] || 0)} v`;
      const del = document.createElement('button');
      del.className = 'del';
      del.title = 'Remove this group';
      del.textContent = '×';
      del.dataset.testid = `group-delete-${k}`;
      del.addEventListener('click', (/** @type {Event} */ e) => {
        e.stopPropagation();
        this.actions.removeGroup(k);
      });
      li.append(sw, name, count, del);
      li.addEventListener('click', () => this.actions.selectGroup(k));
      ul.appendChild(li);
    });
    const roi = counts.roi ? fmtInt(counts.roi) : `whole mesh (${fmtInt(nVertices)})`;
    const fixedSw = `<span class="swatch-inline" style="color:${cssColor(FIXED_COLOR)}">■</span>`;
    $('sel-counts').innerHTML = `ROI: ${roi} · ${fixedSw} anchors: ${fmtInt(counts.fixed)}`;
  }
}
