// The banner that offers to restore a saved session: its description and Restore / Discard buttons.
import './offer.css';

/**
 * Show the offer over `parent`. After onRestore() (unless it returns false) or onDiscard() the banner goes away.
 * Returns {close()} to take it away without an answer, setText(text) to describe it again and `open` (false once
 * it went away).
 * @param {HTMLElement} parent
 * @param {{text: string, onRestore: () => boolean, onDiscard: () => void}} offer
 * @returns {{open: boolean, close: () => void, setText: (text: string) => void}}
 */
export function showRestoreOffer(parent, { text, onRestore, onDiscard }) {
  const box = document.createElement('div');
  box.id = 'restore-offer';
  box.dataset.testid = 'restore-offer';
  box.setAttribute('role', 'alertdialog');
  box.setAttribute('aria-label', 'Restore unsaved work');
  const msg = document.createElement('span');
  msg.className = 'text';
  msg.textContent = text;
  const restore = document.createElement('button');
  restore.className = 'primary';
  restore.textContent = 'Restore';
  restore.dataset.testid = 'restore-accept';
  const discard = document.createElement('button');
  discard.textContent = 'Discard';
  discard.dataset.testid = 'restore-discard';
  box.append(msg, restore, discard);
  parent.appendChild(box);
  /** @type {{open: boolean, close: () => void, setText: (text: string) => void}} */
  const offer = {
    open: true,
    close: () => {
      offer.open = false;
      box.remove();
    },
    setText: (t) => {
      msg.textContent = t;
    },
  };
  const close = () => offer.close();
  restore.addEventListener('click', () => {
    if (onRestore() !== false) close();
  });
  discard.addEventListener('click', () => {
    close();
    onDiscard();
  });
  return offer;
}
