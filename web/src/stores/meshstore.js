// The mesh the page shows and what the server said of it: its name and counts, the file's vertex numbering when
// repair renumbered it, whether repair changed it, where it came from (what a restore loads again), the server's
// limits and built-in models, and whether the session is ready (greeted, in our protocol version, a mesh shown).
// Only this store writes its fields: the others tell it what happened through its methods.

/** @typedef {import('../protocol.js').WelcomeServerMessage} WelcomeServerMessage */
/** @typedef {import('../protocol.js').MeshServerMessage} MeshServerMessage */

/**
 * The server's limits (welcome.limits): upload bytes and vertices at least, 0 while unknown.
 * @typedef {{max_upload_bytes: number, max_vertices: number, [name: string]: any}} Limits
 */

/**
 * Where the session's rest mesh comes from (snapshot.js builtinSource, fileSource): a built-in model by name, or a
 * mesh file's bytes; `repaired`: the bytes are a mesh that repair changed when its file was loaded; `density`: a
 * picture's, when it was meshed again at another density than the one it opens with.
 * @typedef {{kind: string, key: number, name?: string, filename?: string, bytes?: any, repaired?: boolean,
 *   density?: string}} MeshSource
 */

export class MeshStore {
  #ready = false;
  #incompatible = false;
  /** @type {string|null} */
  #name = null;
  #builtin = false;
  #nFaces = 0;
  /** @type {Int32Array|null} */
  #vertexMap = null;
  #repaired = false;
  /** @type {MeshSource|null} */
  #source = null;
  /** @type {Limits} */
  #limits = { max_upload_bytes: 0, max_vertices: 0 };
  /** @type {string[]} */
  #builtins = [];
  #lastSeq = -1;

  /** The session can be edited: the server greeted this page in its protocol version and a mesh is shown. */
  get ready() {
    return this.#ready;
  }

  /** The server speaks another protocol version: its messages are not read. */
  get incompatible() {
    return this.#incompatible;
  }

  /** @returns {string|null} the model's name (null before the first mesh) */
  get name() {
    return this.#name;
  }

  /** The mesh shown is the built-in model of its name (the server says so: a file may share a built-in's name). */
  get builtin() {
    return this.#builtin;
  }

  /** The number of triangles of the mesh shown. */
  get nFaces() {
    return this.#nFaces;
  }

  /** @returns {Int32Array|null} mesh vertex of each vertex of the mesh file, when repair renumbered them */
  get vertexMap() {
    return this.#vertexMap;
  }

  /** Repair changed the mesh: its triangles are not the file's. */
  get repaired() {
    return this.#repaired;
  }

  /** @returns {Readonly<MeshSource>|null} where the current mesh came from */
  get source() {
    return this.#source;
  }

  /** @returns {Readonly<Limits>} */
  get limits() {
    return this.#limits;
  }

  /** @returns {readonly string[]} names of the built-in models */
  get builtins() {
    return this.#builtins;
  }

  /** The newest drag request the shape shown answers (-1: none since the mesh arrived). */
  get lastSeq() {
    return this.#lastSeq;
  }

  /**
   * The server greeted the page: false when it speaks another protocol version (`ours`), which makes it not ready.
   * @param {WelcomeServerMessage} msg
   * @param {number} ours
   */
  welcomed(msg, ours) {
    this.#incompatible = msg.protocol !== ours;
    if (this.#incompatible) {
      this.#ready = false;
      return false;
    }
    this.#builtins = msg.builtin_meshes || [];
    this.#limits = { ...this.#limits, ...(msg.limits || {}) };
    return true;
  }

  /**
   * A mesh arrived and is shown; `vertexMap`: its file's numbering (protocol.js meshArrays).
   * @param {MeshServerMessage} msg
   * @param {Int32Array|null} vertexMap
   */
  shown(msg, vertexMap) {
    this.#name = msg.name;
    this.#builtin = !!msg.builtin;
    this.#nFaces = msg.n_faces;
    this.#vertexMap = vertexMap; // constraints documents name the file's vertices (numbering.js)
    // a picture's mesh is no file's (its pins name its own triangles); its report only describes it
    this.#repaired = (msg.report || []).length > 0 && !msg.picture;
    this.#lastSeq = -1;
  }

  /** The mesh shown was set up (selection, gizmo, timeline, constraint sync): the session can be edited. */
  setUp() {
    this.#ready = true;
  }

  /** The connection went away (lost, or refused by a full server): the session cannot be edited. */
  connectionLost() {
    this.#ready = false;
  }

  /**
   * The shape shown answers the drag request `seq`.
   * @param {number} seq
   */
  dragAnswered(seq) {
    this.#lastSeq = seq;
  }

  /**
   * Where the mesh shown comes from is known (what a restore loads again).
   * @param {MeshSource} source
   */
  sourceKnown(source) {
    this.#source = source;
  }

  /** The source is a PLY written from a repaired mesh: still not the file's triangles. */
  sourceArrived() {
    if (this.#source?.repaired) this.#repaired = true;
  }
}
