// The studio's 3D view: a Three.js scene with the solved mesh (coloured by vertex role, optionally wireframed),
// the mesh file's own colours or texture when it has them, the camera and its orbit controls. It takes new
// positions from the server's frames (all vertices, or the movable subset) and keeps normals and bounds up to date
// in place; the role palette lives in rolecolors.js and the lights and floor grid in stage.js.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { SubsetNormals, VertexFaces, computeBounds, computeNormals } from './normals.js';
import { BASE_LIN, fillRoleColors } from './rolecolors.js';
import { addLights, floorGrid, frameSphere } from './stage.js';
import { RenderMesh, textureParts } from './texture.js';
import { DepthLayers, WIRE_COLOR, WIRE_OPACITY, validLayers } from './depthlayers.js';

/**
 * The positions, index and bounds of a geometry of the viewer: setMesh gives every geometry it makes Float32Array
 * positions, an index, a bounding box and a bounding sphere, which are kept up to date in place and never replaced.
 * @param {THREE.BufferGeometry} g
 */
function partsOf(g) {
  return {
    positions: /** @type {Float32Array} */ (g.attributes.position.array),
    faces: /** @type {Uint32Array} */ (/** @type {THREE.BufferAttribute} */ (g.index).array),
    box: /** @type {THREE.Box3} */ (g.boundingBox),
    sphere: /** @type {THREE.Sphere} */ (g.boundingSphere),
  };
}

export class Viewer {
  /** @param {HTMLElement|null} canvas the page's canvas, in an element whose size it takes */
  constructor(canvas) {
    if (!(canvas instanceof HTMLCanvasElement)) throw new Error('the viewer needs a canvas element');
    const frame = canvas.parentElement;
    if (!frame) throw new Error('the viewer canvas must be placed in the page');
    this.canvas = canvas;
    this.frame = frame;
    this.wireOverlay = false;
    /** @type {'y'|'z'} the axis drawn up: the view turns, the mesh's coordinates stay as they are */
    this.upAxis = 'y';
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setClearColor(0x000000, 0);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
    this.camera.position.set(0, 0, 3);

    addLights(this.scene, this.camera);
    this.scene.add(this.camera);

    this.material = new THREE.MeshStandardMaterial({
      vertexColors: true,
      roughness: 0.55,
      metalness: 0.0,
      side: THREE.DoubleSide,
      polygonOffset: true,
      polygonOffsetFactor: 1,
      polygonOffsetUnits: 1,
    });
    this.wireMaterial = new THREE.MeshBasicMaterial({
      color: WIRE_COLOR, wireframe: true, transparent: true, opacity: WIRE_OPACITY });
    /** @type {THREE.BufferGeometry|null} */
    this.geometry = null;
    /** @type {THREE.Mesh<THREE.BufferGeometry, THREE.MeshStandardMaterial>|null} */
    this.mesh = null;
    /** @type {import('./texture.js').Look|null} the mesh file's colours and texture */
    this.look = null;
    /** @type {RenderMesh|null} the textured render mesh, drawn instead of the solved mesh in texture view */
    this.textured = null;
    /** @type {'texture'|'colours'|'plain'} */
    this.surface = 'plain';
    this._heat = false; // the distortion heat map is shown (on the solved mesh, so the texture steps aside)
    /** @type {Float32Array|null} RGBA role tint per solved vertex, gathered onto the render mesh */
    this._tint = null;
    /** @type {THREE.Mesh<THREE.BufferGeometry, THREE.MeshBasicMaterial>|null} */
    this.wire = null;
    /** @type {THREE.Mesh<THREE.BufferGeometry, THREE.MeshStandardMaterial>|null} the solved mesh's triangles in a
     * picture's pin-depth order (drawOrder), drawn in place of it: the solved mesh stays for picking */
    this.ordered = null;
    /** @type {number[]|null} the drawing order given last */
    this._order = null;
    /** @type {number[]|null} the number of its triangles at each depth, back to front (with the order) */
    this._layers = null;
    /** @type {DepthLayers|null} a drawing order's layers painted in turn, each with its edges under the wireframe
     * overlay (a layer drawn over another hides its edges too) */
    this.layered = null;
    /** @type {THREE.GridHelper|null} */
    this.grid = null;
    this.radius = 1;
    /** @type {VertexFaces|null} vertex→face adjacency, built at the first subset frame */
    this._adjacency = null;
    /** @type {SubsetNormals|null} */
    this._subsetNormals = null;

    /** @type {OrbitControls|null} created by attachControls so other pointer handlers can be registered first */
    this.controls = null;
    this._renderQueued = false;
    this._resize = () => this.resize();
    window.addEventListener('resize', this._resize);
    new ResizeObserver(this._resize).observe(frame);
    this.resize();
  }

  attachControls() {
    const controls = new OrbitControls(this.camera, this.canvas);
    this.controls = controls;
    controls.enableDamping = false;
    controls.mouseButtons = { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.PAN };
    controls.addEventListener('change', () => this.requestRender());
  }

  resize() {
    const el = this.frame;
    const w = Math.max(1, el.clientWidth);
    const h = Math.max(1, el.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  /**
   * Replace the mesh.
   * @param {Float32Array} positions copied
   * @param {Uint32Array} indices copied
   */
  setMesh(positions, indices) {
    this._dropLook();
    this._dropOrdered();
    if (this.mesh) this.scene.remove(this.mesh);
    if (this.wire) this.scene.remove(this.wire);
    this.geometry?.dispose();
    const g = new THREE.BufferGeometry();
    const position = new THREE.BufferAttribute(new Float32Array(positions), 3);
    const index = new THREE.BufferAttribute(new Uint32Array(indices), 1);
    const normal = new THREE.BufferAttribute(new Float32Array(positions.length), 3);
    g.setAttribute('position', position);
    g.setIndex(index);
    const colors = new Float32Array(positions.length);
    for (let i = 0; i < colors.length; i += 3) colors.set(BASE_LIN, i);
    g.setAttribute('color', new THREE.BufferAttribute(colors, 3));
    g.setAttribute('normal', normal);
    computeNormals(position.array, index.array, normal.array);
    const box = new THREE.Box3();
    const sphere = new THREE.Sphere();
    g.boundingBox = box;
    g.boundingSphere = sphere;
    computeBounds(position.array, box, sphere);
    this.geometry = g;
    this._adjacency = null;
    this._subsetNormals = null;
    this.mesh = new THREE.Mesh(g, this.material);
    const wire = new THREE.Mesh(g, this.wireMaterial);
    this.wire = wire;
    wire.visible = this.wireOverlay;
    wire.raycast = () => {};
    this.scene.add(this.mesh);
    this.scene.add(wire);
    this._placeGrid(box);
    this.fit();
  }

  /**
   * Show the mesh file's look (after setMesh): its texture on a render mesh, or its vertex colours; the view starts
   * in texture view, else in colours view.
   * @param {import('./texture.js').Look} look
   */
  setLook(look) {
    this._dropLook();
    if (!this.geometry) return;
    this.look = look;
    const parts = textureParts(look);
    if (parts) {
      const textured = new RenderMesh(parts, () => this.requestRender());
      this.textured = textured;
      textured.material.flatShading = this.material.flatShading;
      this._tint = new Float32Array(4 * this.nVertices);
      const g = this.geometry;
      const { box, sphere } = partsOf(g);
      textured.follow(g.attributes.position.array, g.attributes.normal.array, box, sphere);
      this.scene.add(textured.mesh);
    }
    this.surface = this.textured ? 'texture' : look.colorsLinear ? 'colours' : 'plain';
    this._applySurface();
  }

  _dropLook() {
    if (this.textured) {
      this.scene.remove(this.textured.mesh);
      this.textured.dispose();
    }
    this.textured = null;
    this.look = null;
    this._tint = null;
    this.surface = 'plain';
    if (this.mesh) this.mesh.visible = true;
  }

  /** The surface views this mesh offers, in the panel's order ('plain' always). */
  get surfaces() {
    /** @type {('texture'|'colours'|'plain')[]} */
    const out = [];
    if (this.textured) out.push('texture');
    if (this.look?.colorsLinear) out.push('colours');
    out.push('plain');
    return out;
  }

  /** The texture image is decoded and drawn (true without a texture to wait for). */
  get textureReady() {
    return !this.textured || this.textured.ready || this.textured.failed;
  }

  /**
   * Draw the surface with its texture, its file's vertex colours or plain; the caller then repaints the colours.
   * @param {'texture'|'colours'|'plain'} mode
   */
  setSurface(mode) {
    if (!this.surfaces.includes(mode)) return;
    this.surface = mode;
    this._applySurface();
  }

  /**
   * The heat map is shown or not: it is drawn on the solved mesh, so texture view steps aside meanwhile.
   * @param {boolean} on
   */
  setHeatShown(on) {
    this._heat = on;
    this._applySurface();
  }

  /**
   * Draw the triangles in `order` (later over earlier where they overlap: a picture's pin depths), or in the mesh's
   * own order (null): the textured render mesh (whose triangles are the solved mesh's for a picture) and the solved
   * mesh of the other surface views and the heat map alike. The solved mesh keeps its index (picking and point
   * handles name its triangles): a copy of it in that order is drawn instead. With `layers` (the runs of the order
   * that share a depth) the layers are painted in turn, the wireframe overlay's edges with each (DepthLayers).
   * @param {number[]|null|undefined} order a permutation of the triangles
   * @param {number[]|null} [layers] the number of triangles of each depth in `order`, back to front
   */
  drawOrder(order, layers = null) {
    this.textured?.drawOrder(order);
    const g = this.geometry;
    const index = g ? /** @type {THREE.BufferAttribute} */ (g.index) : null;
    if (!g || !index || !order || order.length !== index.count / 3) {
      this._order = null;
    } else if (!this._order || this._order.length !== order.length || this._order.some((f, j) => f !== order[j])) {
      const faces = /** @type {Uint32Array} */ (index.array);
      if (!this.ordered) {
        // the same attributes (positions, normals, colours: every update shows), its own index
        const drawn = new THREE.BufferGeometry();
        for (const name of ['position', 'normal', 'color']) drawn.setAttribute(name, g.attributes[name]);
        drawn.setIndex(new THREE.BufferAttribute(new Uint32Array(faces.length), 1));
        drawn.boundingBox = g.boundingBox;
        drawn.boundingSphere = g.boundingSphere;
        this.ordered = new THREE.Mesh(drawn, this.material);
        this.ordered.raycast = () => {}; // picking uses the solved mesh
        this.scene.add(this.ordered);
      }
      const drawnIndex = /** @type {THREE.BufferAttribute} */ (this.ordered.geometry.index);
      const out = /** @type {Uint32Array} */ (drawnIndex.array);
      order.forEach((f, j) => out.set(faces.subarray(3 * f, 3 * f + 3), 3 * j));
      drawnIndex.needsUpdate = true;
      this._order = order.slice();
    }
    this._layers = this._order && validLayers(layers, this._order.length) ? layers.slice() : null;
    this._applySurface();
  }

  /** Drop the ordered copy of the solved mesh (with the solved mesh, whose attributes it shares). */
  _dropOrdered() {
    this.layered?.drop();
    this._layers = null;
    if (this.ordered) {
      this.scene.remove(this.ordered);
      this.ordered.geometry.dispose();
    }
    this.ordered = null;
    this._order = null;
  }

  _applySurface() {
    const textured = this.surface === 'texture' && !!this.textured && !this._heat;
    const ordered = !!this.ordered && !!this._order;
    if (this.mesh) this.mesh.visible = !textured && !ordered;
    if (this.ordered) this.ordered.visible = !textured && ordered;
    if (this.textured) this.textured.mesh.visible = textured;
    const fill = textured ? this.textured?.mesh : this.ordered;
    const layers = ordered ? this._layers : null;
    const index = this.ordered?.geometry.index;
    const layered = !!(fill && layers && index && this.geometry);
    if (fill && layers && index && this.geometry) {
      // painted in turn, in place of the whole mesh and its overlay: a layer drawn over another hides its edges too
      this.layered ??= new DepthLayers(this.scene);
      const position = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.position);
      this.layered.show(fill, position, index, layers, this.wireOverlay);
      fill.visible = false;
    } else {
      this.layered?.hide();
    }
    if (this.wire) this.wire.visible = this.wireOverlay && !layered;
    this.requestRender();
  }

  /** The number of layers the wireframe overlay is drawn in (0: none, or over the whole mesh at once). */
  get wireLayers() {
    return this.layered?.wire ? this.layered.nLayers : 0;
  }

  get nVertices() {
    return this.geometry ? this.geometry.attributes.position.count : 0;
  }

  /** The mesh's triangles (3 vertex indices each), or null without a mesh. */
  get faces() {
    return this.geometry ? partsOf(this.geometry).faces : null;
  }

  /** The mesh's bounding box (kept up to date by every position change), or null without a mesh. */
  get box() {
    return this.geometry ? partsOf(this.geometry).box : null;
  }

  get positions() {
    return this.geometry ? partsOf(this.geometry).positions : new Float32Array(0);
  }

  /**
   * Overwrite the vertex positions.
   * @param {Float32Array} array of the right length
   */
  updatePositions(array) {
    const g = this.geometry;
    if (!g) return;
    const attr = /** @type {THREE.BufferAttribute} */ (g.attributes.position);
    if (array.length !== attr.array.length) return;
    attr.array.set(array);
    attr.clearUpdateRanges();
    const normal = /** @type {THREE.BufferAttribute} */ (g.attributes.normal);
    computeNormals(attr.array, partsOf(g).faces, normal.array);
    normal.clearUpdateRanges();
    normal.needsUpdate = true;
    this._positionsChanged(g, attr);
  }

  /**
   * Overwrite the positions of vertices `indices` by `values` (3 per index).
   * @param {Uint32Array} indices
   * @param {Float32Array} values
   */
  updateSubset(indices, values) {
    const g = this.geometry;
    if (!g || !indices.length) return;
    const attr = /** @type {THREE.BufferAttribute} */ (g.attributes.position);
    const a = attr.array;
    let sn = this._subsetNormals;
    if (sn?.movable !== indices) {
      this._adjacency ??= new VertexFaces(partsOf(g).faces, this.nVertices);
      sn = this._subsetNormals = new SubsetNormals(this._adjacency, indices);
    }
    for (let k = 0, o = 0; k < indices.length; k++, o += 3) {
      const i = 3 * indices[k];
      a[i] = values[o];
      a[i + 1] = values[o + 1];
      a[i + 2] = values[o + 2];
    }
    const first = indices[0], last = indices[indices.length - 1];
    attr.clearUpdateRanges();
    attr.addUpdateRange(3 * first, 3 * (last - first + 1));
    const normal = /** @type {THREE.BufferAttribute} */ (g.attributes.normal);
    sn.update(a, normal.array);
    normal.clearUpdateRanges();
    normal.addUpdateRange(3 * sn.first, 3 * (sn.last - sn.first + 1));
    normal.needsUpdate = true;
    this._positionsChanged(g, attr);
  }

  /**
   * @param {THREE.BufferGeometry} g
   * @param {THREE.BufferAttribute} attr its positions
   */
  _positionsChanged(g, attr) {
    attr.needsUpdate = true;
    const { box, sphere } = partsOf(g);
    computeBounds(attr.array, box, sphere);
    if (this.textured) this.textured.follow(attr.array, g.attributes.normal.array, box, sphere);
    this.requestRender();
  }

  /**
   * Colour the vertices by role (see fillRoleColors): roi (or null), role (0 none, 1 fixed, 2+g handle g); `stiff`
   * (per-vertex stiffness, or null) tints painted vertices towards purple, by `stiffStrength` (0..1) of their tint.
   * @param {Uint8Array|null} roi
   * @param {Int16Array} role
   * @param {Float64Array|null} [stiff]
   * @param {number} [stiffStrength]
   */
  updateColors(roi, role, stiff = null, stiffStrength = 0) {
    if (!this.geometry) return;
    const attr = this.geometry.attributes.color;
    // colours and texture views: painted roles are mixed over the file's colours or the texture
    const file = this.surface === 'colours' ? this.look?.colorsLinear ?? null : null;
    const textured = this.surface === 'texture' ? this.textured : null;
    const tint = textured ? this._tint : null;
    fillRoleColors(attr.array, tint, file, roi, role, stiff, stiffStrength);
    attr.needsUpdate = true;
    if (textured && tint) textured.tint(tint);
    this.requestRender();
  }

  /** @param {boolean} flat */
  setFlatShading(flat) {
    this.material.flatShading = flat;
    this.material.needsUpdate = true;
    if (this.textured) {
      this.textured.material.flatShading = flat;
      this.textured.material.needsUpdate = true;
    }
    this.requestRender();
  }

  /**
   * Draw the Y axis or the Z axis up (a Z-up model, as CAD and scanning tools write them, stands on the floor):
   * the camera turns and its orbit follows; the mesh and everything sent to the server keep their coordinates.
   * @param {'y'|'z'} axis
   */
  setUpAxis(axis) {
    const up = axis === 'z' ? 'z' : 'y';
    if (up === this.upAxis) return;
    this.upAxis = up;
    this.camera.up.set(0, up === 'y' ? 1 : 0, up === 'z' ? 1 : 0);
    if (this.controls) {
      // OrbitControls measures its angles about the up axis it was made with: aim them at the new one
      const c = /** @type {any} its private frame of the orbit */ (this.controls);
      c._quat.setFromUnitVectors(this.camera.up, new THREE.Vector3(0, 1, 0));
      c._quatInverse.copy(c._quat).invert();
    }
    if (this.geometry) this._placeGrid(partsOf(this.geometry).box);
    this.fit();
  }

  /** @param {boolean} on */
  setWireframe(on) {
    this.wireOverlay = on;
    this._applySurface();
  }

  /** @param {THREE.Box3} box the mesh's bounds */
  _placeGrid(box) {
    if (this.grid) {
      this.scene.remove(this.grid);
      this.grid.geometry.dispose();
    }
    this.grid = floorGrid(box, this.upAxis);
    this.scene.add(this.grid);
  }

  /** Frame the whole mesh. */
  fit() {
    if (!this.geometry) return;
    // the bounding sphere is kept up to date by every position change
    this.radius = frameSphere(this.camera, this.controls, partsOf(this.geometry).sphere);
    this.requestRender();
  }

  /**
   * World units per CSS pixel at distance `point` from the camera.
   * @param {THREE.Vector3} point
   */
  worldPerPixel(point) {
    const d = this.camera.position.distanceTo(point);
    const h = this.canvas.clientHeight || 1;
    return (2 * d * Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2)) / h;
  }

  /**
   * CSS pixel coordinates (relative to the canvas) of a world point.
   * @param {ArrayLike<number>} p
   */
  project(p) {
    const v = new THREE.Vector3(p[0], p[1], p[2]).project(this.camera);
    return [((v.x + 1) / 2) * this.canvas.clientWidth, ((1 - v.y) / 2) * this.canvas.clientHeight];
  }

  requestRender() {
    if (this._renderQueued) return;
    this._renderQueued = true;
    requestAnimationFrame(() => {
      this._renderQueued = false;
      this.render();
    });
  }

  render() {
    this.renderer.render(this.scene, this.camera);
  }
}
