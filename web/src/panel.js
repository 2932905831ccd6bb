// Side panel: controls bound to studio actions, and the read-outs (groups, counts, statistics, status).
import { EXPORT_FORMATS, PARAMS } from './protocol.js';
import { cssColor, FIXED_COLOR, groupColor } from './rolecolors.js';

/**
 * A panel element by id (form controls of several kinds: typed loosely).
 * @param {string} id
 * @returns {any}
 */
const $ = (id) => document.getElementById(id);

/** The control an event came from. @param {Event} e @returns {any} */
const source = (e) => e.target;

function fmtMs(v) {
  if (v === null || v === undefined || !Number.isFinite(v)) return '–';
  return v >= 100 ? `${v.toFixed(0)} ms` : `${v.toFixed(1)} ms`;
}

function fmtInt(v) {
  return Number.isFinite(v) ? v.toLocaleString('en-US') : '–';
}

/** A count with its noun, singular for 1: "1 iteration", "3,000 iterations". */
export function countOf(n, noun) {
  return `${fmtInt(n)} ${n === 1 ? noun : `${noun}s`}`;
}

/**
 * The Shape line's text for a `settle` message.
 * @param {{status: string, iterations?: number, energy?: number|null}} msg
 */
export function settleText(msg) {
  const n = Number.isFinite(msg.iterations) ? msg.iterations : 0;
  const after = n > 0 ? ` after ${countOf(n, 'iteration')}` : '';
  const energy = Number.isFinite(msg.energy) ? `, energy ${msg.energy.toPrecision(6)}` : '';
  switch (msg.status) {
    case 'settling':
      return `settling…${after}${energy}`;
    case 'settled':
      return `settled${after}${energy}`;
    case 'stopped': // a request interrupted it; it resumes once the requests are answered
      return `paused (editing)${after}${energy}`;
    case 'unconverged': // the server's iteration cap was reached
      return `not converged after ${countOf(n, 'iteration')}${energy}`;
    default:
      return `${msg.status}${after}${energy}`;
  }
}

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

export class Panel {
  /** @param {object} actions callbacks invoked by the controls (see main.js) */
  constructor(actions) {
    this.actions = actions;
    this._statusTimer = null;
    this.enabled = true; // the controls take input (not while the server is away)

    $('builtin-select').addEventListener('change', (e) => actions.loadBuiltin(source(e).value));
    $('btn-open').addEventListener('click', () => $('file-input').click());
    $('file-input').addEventListener('change', (e) => {
      const f = source(e).files?.[0];
      source(e).value = '';
      if (f) actions.uploadFile(f);
    });
    this._segment('tool-seg', 'tool', (v) => actions.setTool(v));
    this._segment('role-seg', 'role', (v) => actions.setRole(v));
    this._segment('gizmo-seg', 'gizmo', (v) => actions.setGizmoMode(v));
    this._segment('surface-seg', 'surface', (v) => actions.setSurface(v));

    const radius = $('brush-radius');
    radius.addEventListener('input', () => actions.setBrushRadius(Number(radius.value)));
    $('brush-units').addEventListener('change', (e) => actions.setBrushUnits(source(e).value));
    $('front-only').addEventListener('change', (e) => actions.setFrontOnly(source(e).checked));
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
    $('energy').addEventListener('change', (e) => actions.setParams({ energy: source(e).value }));
    $('weights').addEventListener('change', (e) => actions.setParams({ weights: source(e).value }));

    for (const format of EXPORT_FORMATS) {
      const b = document.createElement('button');
      b.id = `btn-export-${format}`;
      b.dataset.testid = `export-${format}`;
      b.textContent = `Export ${format.toUpperCase()}`;
      b.addEventListener('click', () => actions.send({ type: 'export', format }));
      $('export-buttons').appendChild(b);
    }
    $('btn-save-constraints').addEventListener('click', () => actions.saveConstraints());
    $('btn-load-constraints').addEventListener('click', () => $('constraints-input').click());
    $('constraints-input').addEventListener('change', (e) => {
      const f = source(e).files?.[0];
      source(e).value = '';
      if (f) actions.loadConstraintsFile(f);
    });

    $('flat-shading').addEventListener('change', (e) => actions.setFlatShading(source(e).checked));
    $('wireframe').addEventListener('change', (e) => actions.setWireframe(source(e).checked));
    $('btn-fit').addEventListener('click', () => actions.fit());
    $('btn-reconnect').addEventListener('click', () => actions.reconnect());
    $('status-close').addEventListener('click', () => this.hideStatus());
  }

  _segment(id, key, onPick) {
    const el = $(id);
    el.addEventListener('click', (e) => {
      const b = source(e).closest('button');
      if (b && !b.disabled) onPick(b.dataset[key]);
    });
  }

  setSegment(id, key, value) {
    for (const b of $(id).querySelectorAll('button')) b.classList.toggle('active', b.dataset[key] === value);
  }

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

  setBuiltins(names, current) {
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
    this.setCurrentModel(current);
  }

  /** Show the model loaded: a built-in one selected in the list, any other (a file) by its name at the list's head. */
  setCurrentModel(name) {
    const sel = /** @type {HTMLSelectElement} */ ($('builtin-select'));
    const known = Array.from(sel.options).some((o) => o.value === name && name);
    const head = sel.options[0];
    if (head && head.value === '') head.textContent = !known && name ? `${name} (file)` : 'Built-in model…';
    sel.value = known ? name : '';
  }

  setMeshInfo(text) {
    $('mesh-info').textContent = text;
  }

  /** A new mesh arrived (the server's mesh message): its name and counts, and the repairs made loading it. */
  meshLoaded(msg) {
    const n = (x) => x.toLocaleString('en-US');
    this.setCurrentModel(msg.name);
    this.setMeshInfo(`${msg.name}: ${n(msg.n_vertices)} vertices, ${n(msg.n_faces)} faces`);
    this.setStats({ n_vertices: msg.n_vertices, n_faces: msg.n_faces, ups: NaN, latency_ms: null, ms_per_iteration: null });
    this.resetSettle(); // the server says how the new mesh's shape settles
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

  setParams(p) {
    if (!p) return;
    if (Number.isFinite(p.iterations)) {
      const v = Math.max(PARAMS.iterations.min, Math.min(PARAMS.iterations.max, p.iterations));
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
  }

  setHistory(canUndo, canRedo) {
    $('btn-undo').disabled = !canUndo;
    $('btn-redo').disabled = !canRedo;
  }

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

  /** Connected, but the server has not greeted this tab yet: it is preparing the solver (compiling, first run). */
  preparingSolver() {
    this.setConnection('preparing');
    this.showStatus('Connected. The server is preparing the solver: the first run after an install compiles it, '
      + 'which takes up to a minute. Editing starts as soon as it is ready.', 'info', 0, 'preparing');
  }

  /** The server speaks another protocol version (a page left open across an upgrade): nothing is sent. */
  protocolMismatch(ours, theirs) {
    this.setEnabled(false);
    this.showStatus(`This page speaks version ${ours} of the studio protocol and the server version ${theirs}: `
      + 'reload the page.', 'error', 0, 'connection');
  }

  /**
   * state: 'open', 'connecting', 'preparing' (connected, the server is not ready yet), 'closed', 'reconnecting' or
   * 'full' (the server refused this tab); retry:
   * {attempt, delayMs} of the next try.
   */
  setConnection(state, retry = null) {
    const dot = $('conn-dot');
    dot.className = `dot ${state === 'open' ? 'ok' : state === 'connecting' || state === 'preparing' ? '' : 'bad'}`;
    const text = {
      open: 'connected', closed: 'disconnected', connecting: 'connecting…', reconnecting: 'reconnecting…',
      full: 'server full', preparing: 'preparing the solver…',
    };
    $('conn-text').textContent = text[state] ?? state;
    const next = retry ? `next try in ${(retry.delayMs / 1000).toFixed(1)} s` : '';
    $('conn-text').title = retry?.attempt ? `attempt ${retry.attempt}, ${next}` : next;
    // while reconnecting, the retries run by themselves; a full server is worth asking again after a tab closed
    $('btn-reconnect').hidden = state !== 'closed' && state !== 'full';
  }

  /** groups: [{id, partner?}] (partner: the id of its mirror partner), active: index, roi/fixed counts. */
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
      del.addEventListener('click', (e) => {
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

  setStats(s) {
    const set = (id, v) => ($(id).textContent = v);
    if ('n_vertices' in s) set('st-vertices', fmtInt(s.n_vertices));
    if ('n_faces' in s) set('st-faces', fmtInt(s.n_faces));
    if ('roi_size' in s) set('st-roi', fmtInt(s.roi_size));
    if ('n_free' in s) set('st-free', fmtInt(s.n_free));
    if ('factor_ms' in s) set('st-factor', fmtMs(s.factor_ms));
    if ('ms_per_iteration' in s) set('st-iter', fmtMs(s.ms_per_iteration));
    if ('ups' in s) set('st-ups', Number.isFinite(s.ups) ? s.ups.toFixed(1) : '–');
    if ('latency_ms' in s) set('st-latency', fmtMs(s.latency_ms));
  }

  /**
   * The Shape line from a `settle` message: settling…, settled, paused (editing) or not converged, with the
   * iterations and the energy; `data-status` is the message's status.
   */
  setSettle(msg) {
    this._setShape(settleText(msg), msg.status);
    this._settleBadge(msg);
  }

  /**
   * The badge over the view: the settling's progress while the server iterates, then for a moment how it ended
   * (not for a shape that was settled already, after undo, redo or loading).
   */
  _settleBadge(msg) {
    const badge = $('settle-badge');
    clearTimeout(this._badgeTimer);
    const ran = msg.status === 'settling' || badge.dataset.status === 'settling' || badge.dataset.status === 'stopped';
    if (!ran) {
      badge.hidden = true;
      badge.dataset.status = '';
      return;
    }
    const text = settleText(msg);
    badge.textContent = text.charAt(0).toUpperCase() + text.slice(1);
    badge.dataset.status = msg.status;
    badge.hidden = false;
    if (msg.status !== 'settling' && msg.status !== 'stopped') {
      this._badgeTimer = setTimeout(() => {
        badge.hidden = true;
        badge.dataset.status = '';
      }, 2500);
    }
  }

  /** A new mesh: nothing is known of its shape's settling until the server says. */
  resetSettle() {
    this._setShape('–', '');
    clearTimeout(this._badgeTimer);
    $('settle-badge').hidden = true;
    $('settle-badge').dataset.status = '';
  }

  /** The connection was lost: a settling the line still shows as under way may never finish. */
  settleUnknown() {
    const status = $('st-settle').dataset.status;
    if (status === 'settling' || status === 'stopped') {
      this._setShape('unknown: the connection was lost while it settled', 'interrupted');
      $('settle-badge').hidden = true;
      $('settle-badge').dataset.status = '';
    }
  }

  _setShape(text, status) {
    const cell = $('st-settle');
    cell.textContent = text;
    cell.dataset.status = status;
  }

  /**
   * Show a message in the status bar (kind 'info' or 'error'), hidden after `timeoutMs` (0: until replaced or
   * dismissed). `tag` names what it is about, so that `clearStatus(tag)` takes it away once it no longer holds.
   */
  showStatus(text, kind = 'info', timeoutMs = 0, tag = '') {
    const bar = $('statusbar');
    bar.className = kind;
    bar.dataset.tag = tag;
    $('status-text').textContent = text;
    bar.hidden = false;
    clearTimeout(this._statusTimer);
    if (timeoutMs) this._statusTimer = setTimeout(() => this.hideStatus(), timeoutMs);
  }

  /** True while the status bar shows a message tagged `tag` (see showStatus). */
  showing(tag) {
    return !$('statusbar').hidden && $('statusbar').dataset.tag === tag;
  }

  /**
   * A short hint (a key that does nothing now, and why): shown for `timeoutMs` unless the status bar holds an
   * error, which it must not hide.
   */
  hint(text, timeoutMs = 3000) {
    if (!$('statusbar').hidden && $('statusbar').className === 'error') return;
    this.showStatus(text, 'info', timeoutMs, 'hint');
  }

  /** Hide the status bar if it shows a message tagged `tag` (see showStatus). */
  clearStatus(tag) {
    if (!$('statusbar').hidden && $('statusbar').dataset.tag === tag) this.hideStatus();
  }

  hideStatus() {
    clearTimeout(this._statusTimer);
    $('statusbar').hidden = true;
  }

  setBusy(text) {
    $('busy').hidden = !text;
    if (text) $('busy-text').textContent = text;
  }
}
