// The panel's controls of the point-handle mode and the stiffness brush: the brush's strength (log slider, or
// rigid), its eraser, and the weight of new point handles (empty: hard).
import { byId, byIdAs } from './dom.js';
import { sliderToStiffness, stiffnessLabel } from './stiffness.js';

const $ = (/** @type {string} */ id) => byIdAs(id, HTMLInputElement);

export class PaintModes {
  /**
   * @param {object} opts
   * @param {import('./selection.js').Selection} opts.selection its stiffnessValue is what the brush paints
   * @param {(role: string) => void} opts.setRole
   * @param {(text: string) => void} opts.onWeightProblem
   */
  constructor({ selection, setRole, onWeightProblem }) {
    this.selection = selection;
    this.onWeightProblem = onWeightProblem;
    this.slider = $('stiffness');
    this.rigid = $('stiffness-rigid');
    this.eraser = $('stiffness-erase');
    this.weightInput = $('point-weight');
    this.on = true; // the panel's controls take input
    byId('role-seg-2').addEventListener('click', (e) => {
      const b = /** @type {Element} */ (e.target).closest('button');
      // every button of the row names its role
      if (b instanceof HTMLButtonElement && !b.disabled) setRole(/** @type {string} */ (b.dataset.role));
    });
    const strength = () => {
      this._update();
      setRole('stiffness');
    };
    this.slider.addEventListener('input', strength);
    this.rigid.addEventListener('change', strength);
    this.eraser.addEventListener('change', strength);
    this.weightInput.addEventListener('change', () => {
      this.weight();
      setRole('point');
    });
    // Enter takes the weight and hands the keys back to the shortcuts
    this.weightInput.addEventListener('keydown', (e) => {
      if (e.key === 'Enter') this.weightInput.blur();
    });
    // A decimal comma becomes a point as it is typed or pasted: the number field would take "1,5" as 15 (the comma
    // read as a thousands separator), and its value never shows what was typed.
    this.weightInput.addEventListener('beforeinput', (e) => {
      if (e.inputType === 'insertText' && e.data === ',') {
        e.preventDefault();
        this._insertDecimal();
      }
    });
    this.weightInput.addEventListener('paste', (e) => {
      const text = e.clipboardData?.getData('text/plain') ?? '';
      if (!text.includes(',')) return;
      e.preventDefault();
      const trimmed = text.trim();
      if (/^\d*,\d+$/.test(trimmed) || /^\d+,\d*$/.test(trimmed)) {
        document.execCommand('insertText', false, trimmed.replace(',', '.'));
      } else {
        this.onWeightProblem(`Point weight must be one positive number, such as 1.5 or 1,5; "${trimmed.slice(0, 40)}" `
          + 'was not pasted.');
      }
    });
    // text that is no number ("1e", "--2") leaves the field's value empty and sends no change
    this.weightInput.addEventListener('blur', () => {
      if (this.weightInput.validity.badInput) this.weight();
    });
    this._update();
  }

  /** A decimal comma typed into the weight: a point instead, or a message when the number has one already. */
  _insertDecimal() {
    const field = this.weightInput;
    if (field.value.includes('.') || field.value.toLowerCase().includes('e')) {
      this.onWeightProblem('Point weight takes one decimal separator (a point or a comma), as in 1.5 or 1,5.');
      return;
    }
    document.execCommand('insertText', false, '.');
  }

  _update() {
    const value = this.rigid.checked ? Infinity : sliderToStiffness(Number(this.slider.value));
    this.selection.stiffnessChosen(value);
    this.slider.disabled = !this.on || this.rigid.checked;
    byId('stiffness-val').textContent = stiffnessLabel(value);
  }

  /**
   * Enable the strength slider with the panel's controls (`on`), except while rigid is ticked.
   * @param {boolean} on
   */
  enable(on) {
    this.on = on;
    this.slider.disabled = !on || this.rigid.checked;
  }

  /**
   * Whether a stroke in `role` removes (the modifier held, or the stiffness eraser on).
   * @param {string} role
   * @param {boolean} modifier
   */
  subtract(role, modifier) {
    return modifier || (role === 'stiffness' && this.eraser.checked);
  }

  /** The weight of new point handles: null (hard) when the field is empty or not a positive number. */
  weight() {
    if (this.weightInput.validity.badInput) {
      this.onWeightProblem('Point weight must be a positive number (or empty for a hard handle); what was typed is '
        + 'not a number.');
      this.weightInput.value = '';
      return null;
    }
    const text = this.weightInput.value.trim();
    if (!text) return null;
    const w = Number(text);
    if (Number.isFinite(w) && w > 0) return w;
    this.onWeightProblem(`Point weight must be a positive number (or empty for a hard handle), not "${text}".`);
    this.weightInput.value = '';
    return null;
  }

  /**
   * Mark the active buttons of the second row of roles; show each mode's settings only while it is chosen.
   * @param {string} role
   */
  showRole(role) {
    for (const b of document.querySelectorAll('#role-seg-2 button')) {
      b.classList.toggle('active', /** @type {HTMLElement} */ (b).dataset.role === role);
    }
    const stiffnessRow = document.getElementById('stiffness-row');
    const pointRow = document.getElementById('point-row');
    if (stiffnessRow) stiffnessRow.hidden = role !== 'stiffness';
    if (pointRow) pointRow.hidden = role !== 'point';
  }
}
