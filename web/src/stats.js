// The statistics of live updates: the energy plots (per iteration of the last update, and per update) and the
// updates per second, which decay to zero once dragging stops.
import { LinePlot } from './plot.js';

/** The note that energies below 0 were reported. */
const energyNote = () => /** @type {HTMLElement} */ (document.getElementById('energy-note'));

export class UpdateStats {
  /**
   * @param {object} opts
   * @param {import('./panel.js').Panel} opts.panel the panel (its setStats)
   * @param {() => number|null} opts.latencyMs the connection's last round trip, or null
   */
  constructor({ panel, latencyMs }) {
    this.panel = panel;
    this.latencyMs = latencyMs;
    /** @type {number[]} */
    this.updateTimes = []; // when each solved update of the last second arrived
    this.iterPlot = new LinePlot(/** @type {HTMLCanvasElement} */ (document.getElementById('plot-iter')), { color: '#4c9aff', xLabel: 'iterations' });
    this.timePlot = new LinePlot(/** @type {HTMLCanvasElement} */ (document.getElementById('plot-time')),
      { color: '#f0883e', xLabel: 'updates', maxPoints: 300 });
    setInterval(() => {
      if (this.updateTimes.length) this.panel.setStats({ ups: this._ups() });
    }, 500);
  }

  _ups() {
    const now = performance.now();
    while (this.updateTimes.length && now - this.updateTimes[0] > 1000) this.updateTimes.shift();
    return this.updateTimes.length;
  }

  /** A new mesh: the plots start over, without the note on energies below 0. */
  reset() {
    this.updateTimes = [];
    this.iterPlot.clear();
    this.timePlot.clear();
    energyNote().hidden = true;
  }

  /**
   * Show the note on energies below 0 while the energies last reported include one.
   * @param {number[]} energies
   */
  noteEnergies(energies) {
    energyNote().hidden = !energies.some((e) => e < 0);
  }

  /**
   * A vertices frame of a solve (iterations > 0) arrived: counted, and its last energy noted (drawn later).
   * @param {import('./protocol.js').VerticesServerMessage} msg
   */
  received(msg) {
    this.updateTimes.push(performance.now());
    const energies = (msg.energies || []).filter((e) => e !== null);
    if (energies.length) this.timePlot.push(energies[energies.length - 1], false);
  }

  /**
   * The newest vertices frame of a solve was drawn: its energies, timings and the update rate.
   * @param {import('./protocol.js').VerticesServerMessage} msg
   */
  frame(msg) {
    const energies = (msg.energies || []).filter((e) => e !== null);
    this.iterPlot.set(energies);
    this.timePlot.draw();
    if (energies.length) this.noteEnergies(energies); // a settling frame carries none: its `settle` message does
    const latency = this.latencyMs();
    this.panel.setStats({
      ms_per_iteration: msg.ms_per_iteration,
      ups: this._ups(),
      latency_ms: msg.seq >= 0 && latency !== null ? latency : msg.solve_ms,
    });
  }
}
