// Looking up the studio page's elements by id. The page (index.html) and the modules that drive it are written
// together, so a missing element is a bug of the page, not a state to handle: these lookups fail at once with the
// id in the message, instead of a null that would fail later, far from its cause, and they give the element the
// type its use needs (an input, a select) after checking it.

/**
 * The page's element with this id; throws when the page has none.
 * @param {string} id
 * @returns {HTMLElement}
 */
export function byId(id) {
  const el = document.getElementById(id);
  if (!el) throw new Error(`the page has no element #${id}`);
  return el;
}

/**
 * The page's element with this id, of the given kind (e.g. HTMLInputElement); throws when the page has none or it
 * is of another kind.
 * @template {HTMLElement} T
 * @param {string} id
 * @param {{new (): T, prototype: T}} kind
 * @returns {T}
 */
export function byIdAs(id, kind) {
  const el = byId(id);
  if (!(el instanceof kind)) throw new Error(`the page's element #${id} is not a ${kind.name}`);
  return el;
}

/**
 * The first element under `root` that matches a CSS selector; throws when there is none.
 * @param {ParentNode} root
 * @param {string} selector
 * @returns {HTMLElement}
 */
export function inside(root, selector) {
  const el = root.querySelector(selector);
  if (!(el instanceof HTMLElement)) throw new Error(`the page has no element ${selector} where expected`);
  return el;
}
