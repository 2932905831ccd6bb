// A picture whose pins have depths drawn layer by layer: the runs of its drawing order that share a depth (the
// state's draw_layers), back to front, each layer's triangles and then, with the wireframe overlay on, its edges.
// Where warped parts overlap, the part drawn over the other then hides that one's edges as well as its triangles.
// The layers are painted in turn, whatever their depth values say: the parts lie in one plane, where the depth test
// cannot tell them apart (coplanar triangles of two parts fight over the pixels). Their triangles still write depth,
// so whatever else the scene holds (pins, the floor grid) is hidden behind the picture as before.
//
// Every layer is a group of the geometry it draws from (no copy of any buffer): one object per layer whose material
// array holds a material for that layer's group alone, placed by renderOrder before the scene's other opaque objects.
import * as THREE from 'three';

/** The wireframe overlay's colour and opacity (as the viewer's over a mesh drawn whole). */
export const WIRE_COLOR = 0x111418;
export const WIRE_OPACITY = 0.28;

/**
 * The edges of `faces` (3 vertex indices per triangle) as line segments in the same order: 6 indices per triangle
 * (a–b, b–c, c–a), so the edges of triangles [s, s + n) are the segments' indices [6s, 6s + 6n).
 * @param {ArrayLike<number>} faces
 * @param {Uint32Array} [out] of length 2 · faces.length, filled and returned
 */
export function triangleEdges(faces, out = new Uint32Array(2 * faces.length)) {
  for (let f = 0, o = 0; f < faces.length; f += 3, o += 6) {
    const a = faces[f], b = faces[f + 1], c = faces[f + 2];
    out[o] = a;
    out[o + 1] = b;
    out[o + 2] = b;
    out[o + 3] = c;
    out[o + 4] = c;
    out[o + 5] = a;
  }
  return out;
}

/**
 * Whether `layers` splits `nTriangles` triangles into two or more runs (positive integer counts that add up).
 * @param {unknown} layers
 * @param {number} nTriangles
 * @returns {layers is number[]}
 */
export function validLayers(layers, nTriangles) {
  if (!Array.isArray(layers) || layers.length < 2) return false;
  let sum = 0;
  for (const n of layers) {
    if (!Number.isInteger(n) || n <= 0) return false;
    sum += n;
  }
  return sum === nTriangles;
}

export class DepthLayers {
  /** @param {THREE.Scene} scene */
  constructor(scene) {
    this.scene = scene;
    // blended as the transparent overlay is (colour and alpha), but painted in the opaque pass among the layers
    this.wireMaterial = new THREE.LineBasicMaterial({
      color: WIRE_COLOR, opacity: WIRE_OPACITY, transparent: false, depthWrite: false, depthFunc: THREE.AlwaysDepth,
      blending: THREE.CustomBlending, blendSrc: THREE.SrcAlphaFactor, blendDst: THREE.OneMinusSrcAlphaFactor,
      blendSrcAlpha: THREE.OneFactor, blendDstAlpha: THREE.OneMinusSrcAlphaFactor,
    });
    /** A layer object's material for the groups of the other layers (never drawn). */
    this.skipped = new THREE.MeshBasicMaterial({ visible: false });
    /** @type {THREE.BufferGeometry|null} the edges of the drawn triangles, on the positions they join */
    this.edges = null;
    /** @type {THREE.BufferAttribute|null} the drawing order's index the edges were made from */
    this._index = null;
    this._indexVersion = -1;
    /** @type {THREE.Mesh<THREE.BufferGeometry, THREE.Material>|null} the mesh whose triangles are drawn in layers */
    this._fill = null;
    /** @type {number[]} */
    this._layers = [];
    this._wire = false;
    /** @type {THREE.Object3D[]} per layer: its triangles, then (with the wireframe) its edges */
    this.pieces = [];
  }

  /** The number of layers drawn (0: none). */
  get nLayers() {
    return this.pieces.length && this.pieces[0].visible ? this._layers.length : 0;
  }

  /** Whether the layers are drawn with their edges. */
  get wire() {
    return this.nLayers > 0 && this._wire;
  }

  /**
   * Draw `fill` layer by layer, with each layer's edges over its triangles when `wire` (the caller hides `fill`
   * itself, and gives it to hide() before drawing it whole again).
   * @param {THREE.Mesh<THREE.BufferGeometry, THREE.Material>} fill its index in the drawing order
   * @param {THREE.BufferAttribute} position the positions the edges join (the same points as fill's)
   * @param {THREE.BufferAttribute} index the triangles in the drawing order (3 vertex indices of `position` each)
   * @param {number[]} layers the number of triangles of each layer, back to front (validLayers)
   * @param {boolean} wire
   */
  show(fill, position, index, layers, wire) {
    if (wire) this._edges(position, index);
    const same = fill === this._fill && wire === this._wire && layers.length === this._layers.length
      && layers.every((n, r) => n === this._layers[r]);
    if (!same) this._build(fill, layers, wire);
    fill.material.depthFunc = THREE.AlwaysDepth; // painted in turn (the fill itself is hidden meanwhile)
    for (const p of this.pieces) p.visible = true;
  }

  /** Draw no layers: the viewer draws its meshes whole again. */
  hide() {
    for (const p of this.pieces) p.visible = false;
    if (this._fill) this._fill.material.depthFunc = THREE.LessEqualDepth;
  }

  /**
   * The edges of `index` on `position`, made again when either changed.
   * @param {THREE.BufferAttribute} position
   * @param {THREE.BufferAttribute} index
   */
  _edges(position, index) {
    let edges = this.edges;
    if (!edges || edges.attributes.position !== position) {
      this._clearPieces();
      edges?.dispose(); // its positions belong to a mesh gone
      edges = this.edges = new THREE.BufferGeometry();
      edges.setAttribute('position', position);
      this._index = null;
    }
    if (this._index === index && this._indexVersion === index.version) return;
    let lines = edges.index;
    if (!lines || lines.count !== 2 * index.count) {
      lines = new THREE.BufferAttribute(new Uint32Array(2 * index.count), 1);
      edges.setIndex(lines);
    }
    triangleEdges(/** @type {ArrayLike<number>} */ (index.array), /** @type {Uint32Array} */ (lines.array));
    lines.needsUpdate = true;
    this._index = index;
    this._indexVersion = index.version;
  }

  /**
   * The layers' objects for `fill`: its triangles' groups, and the edges' with `wire`.
   * @param {THREE.Mesh<THREE.BufferGeometry, THREE.Material>} fill
   * @param {number[]} layers
   * @param {boolean} wire
   */
  _build(fill, layers, wire) {
    this._clearPieces();
    this._fill = fill;
    this._layers = layers.slice();
    this._wire = wire;
    const edges = wire ? this.edges : null;
    let start = 0;
    layers.forEach((n, r) => {
      const only = (/** @type {THREE.Material} */ m) => [...new Array(r).fill(this.skipped), m];
      fill.geometry.addGroup(3 * start, 3 * n, r);
      /** @type {THREE.Object3D[]} */
      const parts = [new THREE.Mesh(fill.geometry, only(fill.material))];
      if (edges) {
        edges.addGroup(6 * start, 6 * n, r);
        parts.push(new THREE.LineSegments(edges, only(this.wireMaterial)));
      }
      start += n;
      parts.forEach((p, k) => {
        p.renderOrder = 2 * (r - layers.length) + k; // back to front, before the scene's other opaque objects
        p.frustumCulled = false;
        p.raycast = () => {}; // picking uses the solved mesh
        this.pieces.push(p);
        this.scene.add(p);
      });
    });
  }

  _clearPieces() {
    this.hide();
    for (const p of this.pieces) this.scene.remove(p);
    this.pieces = [];
    this._fill?.geometry.clearGroups();
    this.edges?.clearGroups();
    this._fill = null;
    this._layers = [];
  }

  /** Forget the meshes drawn (they are being replaced): the layers' objects and the edges go. */
  drop() {
    this._clearPieces();
    this.edges?.dispose();
    this.edges = null;
    this._index = null;
  }
}
