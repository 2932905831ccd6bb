// Saved editing sessions in the browser's IndexedDB: one record per page (its selection, shape and parameters) and
// the mesh it needs, stored apart because it changes rarely. Pages hold a Web Lock while they live, so the saved
// session of a page that is still open in another tab is not offered for restoring.

const DB_NAME = 'arap-studio';
const DB_VERSION = 1;
const SESSIONS = 'sessions';
const MESHES = 'meshes';
const LOCK_PREFIX = 'arap-session:';
const KEEP = 5; // saved sessions kept; older ones are deleted

/**
 * A stored session record (autosave.js): what was written, as read back.
 * @typedef {import('./autosave.js').Snapshot & {id: string}} SavedSession
 */

/** @type {Promise<IDBDatabase>|null} */
let dbPromise = null;

/**
 * @template T
 * @param {IDBRequest<T>} req
 * @returns {Promise<T>} its result, once it succeeds
 */
function request(req) {
  return new Promise((resolve, reject) => {
    req.onsuccess = () => resolve(req.result);
    req.onerror = () => reject(req.error);
  });
}

/**
 * @param {IDBTransaction} tx
 * @returns {Promise<void>} settles when the transaction completes or fails
 */
function done(tx) {
  return new Promise((resolve, reject) => {
    tx.oncomplete = () => resolve();
    tx.onabort = () => reject(tx.error || new Error('IndexedDB transaction aborted'));
    tx.onerror = () => reject(tx.error);
  });
}

/** @returns {Promise<IDBDatabase>} */
function open() {
  if (!dbPromise) {
    if (typeof indexedDB === 'undefined') return Promise.reject(new Error('this browser has no IndexedDB'));
    const req = indexedDB.open(DB_NAME, DB_VERSION);
    req.onupgradeneeded = () => {
      const db = req.result;
      if (!db.objectStoreNames.contains(SESSIONS)) db.createObjectStore(SESSIONS, { keyPath: 'id' });
      if (!db.objectStoreNames.contains(MESHES)) db.createObjectStore(MESHES, { keyPath: 'id' });
    };
    dbPromise = request(req);
    dbPromise.catch(() => (dbPromise = null));
  }
  return dbPromise;
}

/** A new id for this page's saved session, locked for as long as the page lives. */
export function newSessionId() {
  const id = globalThis.crypto?.randomUUID?.() ?? `${Date.now().toString(36)}-${Math.random().toString(36).slice(2)}`;
  navigator.locks?.request(LOCK_PREFIX + id, () => new Promise(() => {})).catch(() => {});
  return id;
}

/**
 * Save a session record; `mesh` ({id, ...}) is written too when given (the record names it by `meshId`).
 * @param {object} record
 * @param {{id: string, key: number, bytes: ArrayBuffer}|null} [mesh] a mesh file's bytes, under the source's key
 */
export async function putSession(record, mesh = null) {
  const db = await open();
  const tx = db.transaction([SESSIONS, MESHES], 'readwrite');
  if (mesh) tx.objectStore(MESHES).put(mesh);
  tx.objectStore(SESSIONS).put(record);
  return done(tx);
}

/**
 * Delete a session record and its mesh.
 * @param {string} id
 */
export async function deleteSession(id) {
  const db = await open();
  const tx = db.transaction([SESSIONS, MESHES], 'readwrite');
  tx.objectStore(SESSIONS).delete(id);
  tx.objectStore(MESHES).delete(id);
  return done(tx);
}

/**
 * The mesh stored with a session record, or undefined.
 * @param {string} id the record's
 * @returns {Promise<{id: string, key: number, bytes: ArrayBuffer}|undefined>}
 */
export async function getMesh(id) {
  const db = await open();
  return request(db.transaction(MESHES).objectStore(MESHES).get(id));
}

async function heldIds() {
  if (!navigator.locks?.query) return new Set();
  const { held = [] } = await navigator.locks.query();
  return new Set(held.map((l) => l.name).filter((n) => typeof n === 'string')
    .filter((n) => n.startsWith(LOCK_PREFIX)).map((n) => n.slice(LOCK_PREFIX.length)));
}

/**
 * The newest saved session of a page that is gone (not `ownId`, not open elsewhere), or null. Sessions beyond
 * the newest few are deleted on the way.
 * @param {string} ownId this page's record
 * @returns {Promise<SavedSession|null>}
 */
export async function newestOrphan(ownId) {
  const db = await open();
  /** @type {SavedSession[]} */
  const all = await request(db.transaction(SESSIONS).objectStore(SESSIONS).getAll());
  all.sort((a, b) => b.savedAt - a.savedAt);
  for (const old of all.slice(KEEP)) await deleteSession(old.id);
  const live = await heldIds();
  return all.slice(0, KEEP).find((r) => r.id !== ownId && !live.has(r.id)) ?? null;
}
