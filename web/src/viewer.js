// Three.js scene: the mesh with per-vertex role colours, lights, camera and orbit controls.
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { SubsetNormals, VertexFaces, computeBounds, computeNormals } from './normals.js';
import { stiffnessTint } from './stiffness.js';
import { OUTSIDE_BLEND, RenderMesh, ROLE_BLEND } from './texture.js';

// Role colours in sRGB (as shown in the panel); the vertex colour attribute holds their linear values.
export const BASE_COLOR = [0.78, 0.79, 0.81];
const OUTSIDE_COLOR = [0.55, 0.56, 0.58];
const ROI_COLOR = [0.55, 0.74, 0.95];
export const FIXED_COLOR = [0.9, 0.3, 0.27];
export const STIFF_COLOR = [0.36, 0.16, 0.55];
export const GROUP_COLORS = [
  [1.0, 0.62, 0.1],
  [0.25, 0.78, 0.42],
  [0.66, 0.42, 0.96],
  [0.98, 0.84, 0.16],
  [0.15, 0.8, 0.84],
  [0.95, 0.4, 0.68],
  [0.58, 0.84, 0.2],
  [0.4, 0.52, 1.0],
];

export function groupColor(g) {
  return GROUP_COLORS[g % GROUP_COLORS.length];
}

export function cssColor(rgb) {
  return `rgb(${rgb.map((c) => Math.round(c * 255)).join(',')})`;
}

const srgbToLinear = (c) => (c < 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);
const toLinear = (rgb) => rgb.map(srgbToLinear);
const BASE_LIN = toLinear(BASE_COLOR);
const OUTSIDE_LIN = toLinear(OUTSIDE_COLOR);
const ROI_LIN = toLinear(ROI_COLOR);
const FIXED_LIN = toLinear(FIXED_COLOR);
const GROUP_LIN = GROUP_COLORS.map(toLinear);
const STIFF_LIN = toLinear(STIFF_COLOR);

export class Viewer {
  constructor(canvas) {
    this.canvas = canvas;
    this.wireOverlay = false;
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setClearColor(0x000000, 0);
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
    this.camera.position.set(0, 0, 3);

    // lights follow the camera, so the side facing the viewer is always lit
    this.scene.add(new THREE.HemisphereLight(0xeef2ff, 0x2a2622, 0.55));
    /** @type {Array<[number, number, number[]]>} */
    const lights = [
      [0xffffff, 1.9, [0.6, 0.9, 1]],
      [0xc8d8ff, 0.55, [-1, -0.2, 0.4]],
      [0xfff0e0, 0.35, [0.2, -1, 0.3]],
    ];
    for (const [color, intensity, p] of lights) {
      const light = new THREE.DirectionalLight(color, intensity);
      light.position.set(p[0], p[1], p[2]);
      light.target.position.set(0, 0, 0);
      this.camera.add(light, light.target);
    }
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
    this.wireMaterial = new THREE.MeshBasicMaterial({ color: 0x111418, wireframe: true, transparent: true, opacity: 0.28 });
    this.geometry = null;
    this.mesh = null;
    /** @type {import('./texture.js').Look|null} the mesh file's colours and texture */
    this.look = null;
    /** @type {RenderMesh|null} the textured render mesh, drawn instead of the solved mesh in texture view */
    this.textured = null;
    /** @type {'texture'|'colours'|'plain'} */
    this.surface = 'plain';
    this._heat = false; // the distortion heat map is shown (on the solved mesh, so the texture steps aside)
    this._tint = null; // RGBA role tint per solved vertex, gathered onto the render mesh
    this.wire = null;
    this.grid = null;
    this.radius = 1;

    this.controls = null; // created by attachControls so other pointer handlers can be registered first
    this._renderQueued = false;
    this._resize = () => this.resize();
    window.addEventListener('resize', this._resize);
    new ResizeObserver(this._resize).observe(canvas.parentElement);
    this.resize();
  }

  attachControls() {
    this.controls = new OrbitControls(this.camera, this.canvas);
    this.controls.enableDamping = false;
    this.controls.mouseButtons = { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: THREE.MOUSE.PAN };
    this.controls.addEventListener('change', () => this.requestRender());
  }

  resize() {
    const el = this.canvas.parentElement;
    const w = Math.max(1, el.clientWidth);
    const h = Math.max(1, el.clientHeight);
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.requestRender();
  }

  /** Replace the mesh. positions: Float32Array (copied), indices: Uint32Array (copied). */
  setMesh(positions, indices) {
    this._dropLook();
    if (this.mesh) {
      this.scene.remove(this.mesh);
      this.scene.remove(this.wire);
      this.geometry.dispose();
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(positions), 3));
    g.setIndex(new THREE.BufferAttribute(new Uint32Array(indices), 1));
    const colors = new Float32Array(positions.length);
    for (let i = 0; i < colors.length; i += 3) colors.set(BASE_LIN, i);
    g.setAttribute('color', new THREE.BufferAttribute(colors, 3));
    g.setAttribute('normal', new THREE.BufferAttribute(new Float32Array(positions.length), 3));
    computeNormals(g.attributes.position.array, g.index.array, g.attributes.normal.array);
    g.boundingBox = new THREE.Box3();
    g.boundingSphere = new THREE.Sphere();
    computeBounds(g.attributes.position.array, g.boundingBox, g.boundingSphere);
    this.geometry = g;
    this._adjacency = null; // vertex→face adjacency, built at the first subset frame
    this._subsetNormals = null;
    this.mesh = new THREE.Mesh(g, this.material);
    this.wire = new THREE.Mesh(g, this.wireMaterial);
    this.wire.visible = this.wireOverlay;
    this.wire.raycast = () => {};
    this.scene.add(this.mesh);
    this.scene.add(this.wire);
    this._placeGrid();
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
    if (look.map && look.texture) {
      this.textured = new RenderMesh(look, () => this.requestRender());
      this.textured.material.flatShading = this.material.flatShading;
      this._tint = new Float32Array(4 * this.nVertices);
      const g = this.geometry;
      this.textured.follow(g.attributes.position.array, g.attributes.normal.array, g.boundingBox, g.boundingSphere);
      this.scene.add(this.textured.mesh);
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

  /** Draw the surface with its texture, its file's vertex colours or plain; the caller then repaints the colours. */
  setSurface(mode) {
    if (!this.surfaces.includes(mode)) return;
    this.surface = mode;
    this._applySurface();
  }

  /** The heat map is shown or not: it is drawn on the solved mesh, so texture view steps aside meanwhile. */
  setHeatShown(on) {
    this._heat = on;
    this._applySurface();
  }

  _applySurface() {
    const textured = this.surface === 'texture' && !!this.textured && !this._heat;
    if (this.mesh) this.mesh.visible = !textured;
    if (this.textured) this.textured.mesh.visible = textured;
    this.requestRender();
  }

  get nVertices() {
    return this.geometry ? this.geometry.attributes.position.count : 0;
  }

  get positions() {
    return this.geometry ? this.geometry.attributes.position.array : new Float32Array(0);
  }

  /** Overwrite the vertex positions (a Float32Array of the right length). */
  updatePositions(array) {
    if (!this.geometry) return;
    const attr = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.position);
    if (array.length !== attr.array.length) return;
    attr.array.set(array);
    attr.clearUpdateRanges();
    const normal = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.normal);
    computeNormals(attr.array, this.geometry.index.array, normal.array);
    normal.clearUpdateRanges();
    normal.needsUpdate = true;
    this._positionsChanged(attr);
  }

  /** Overwrite the positions of vertices `indices` (Uint32Array) by `values` (Float32Array, 3 per index). */
  updateSubset(indices, values) {
    if (!this.geometry || !indices.length) return;
    const attr = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.position);
    const a = attr.array;
    if (this._subsetNormals?.movable !== indices) {
      this._adjacency ??= new VertexFaces(/** @type {Uint32Array} */ (this.geometry.index.array), this.nVertices);
      this._subsetNormals = new SubsetNormals(this._adjacency, indices);
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
    const sn = this._subsetNormals;
    const normal = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.normal);
    sn.update(a, normal.array);
    normal.clearUpdateRanges();
    normal.addUpdateRange(3 * sn.first, 3 * (sn.last - sn.first + 1));
    normal.needsUpdate = true;
    this._positionsChanged(attr);
  }

  _positionsChanged(attr) {
    attr.needsUpdate = true;
    const g = this.geometry;
    computeBounds(attr.array, g.boundingBox, g.boundingSphere);
    if (this.textured) this.textured.follow(attr.array, g.attributes.normal.array, g.boundingBox, g.boundingSphere);
    this.requestRender();
  }

  /** Colour vertices by role: roi (Uint8Array or null), role (Int16Array: 0 none, 1 fixed, 2+g handle g). */
  /**
   * Colour the vertices by role; `stiff` (per-vertex stiffness, or null) tints painted vertices towards purple,
   * by `stiffStrength` (0..1) of their tint.
   */
  updateColors(roi, role, stiff = null, stiffStrength = 0) {
    if (!this.geometry) return;
    const attr = this.geometry.attributes.color;
    const c = attr.array;
    const hasRoi = roi !== null;
    // colours and texture views: painted roles are mixed over the file's colours or the texture
    const file = this.surface === 'colours' ? this.look?.colorsLinear ?? null : null;
    const tint = this.surface === 'texture' && this.textured ? this._tint : null;
    for (let i = 0, n = role.length; i < n; i++) {
      const r = role[i];
      let rgb;
      let blend = ROLE_BLEND;
      if (r === 1) rgb = FIXED_LIN;
      else if (r >= 2) rgb = GROUP_LIN[(r - 2) % GROUP_LIN.length];
      else if (hasRoi && !roi[i]) {
        rgb = OUTSIDE_LIN;
        blend = OUTSIDE_BLEND;
      } else {
        rgb = hasRoi ? ROI_LIN : BASE_LIN;
        blend = 0;
      }
      const t = stiff && stiff[i] !== 1 ? stiffStrength * stiffnessTint(stiff[i]) : 0;
      let x = rgb[0] + t * (STIFF_LIN[0] - rgb[0]);
      let y = rgb[1] + t * (STIFF_LIN[1] - rgb[1]);
      let z = rgb[2] + t * (STIFF_LIN[2] - rgb[2]);
      if (blend === 0 && t > 0 && (tint || file)) { // unpainted but stiff: the stiffness colour over the surface
        x = STIFF_LIN[0];
        y = STIFF_LIN[1];
        z = STIFF_LIN[2];
        blend = t;
      }
      if (tint) {
        tint[4 * i] = x;
        tint[4 * i + 1] = y;
        tint[4 * i + 2] = z;
        tint[4 * i + 3] = blend;
      }
      if (file) {
        x = file[3 * i] + blend * (x - file[3 * i]);
        y = file[3 * i + 1] + blend * (y - file[3 * i + 1]);
        z = file[3 * i + 2] + blend * (z - file[3 * i + 2]);
      }
      c[3 * i] = x;
      c[3 * i + 1] = y;
      c[3 * i + 2] = z;
    }
    attr.needsUpdate = true;
    if (tint) this.textured.tint(tint);
    this.requestRender();
  }

  setFlatShading(flat) {
    this.material.flatShading = flat;
    this.material.needsUpdate = true;
    if (this.textured) {
      this.textured.material.flatShading = flat;
      this.textured.material.needsUpdate = true;
    }
    this.requestRender();
  }

  setWireframe(on) {
    this.wireOverlay = on;
    if (this.wire) this.wire.visible = on;
    this.requestRender();
  }

  _placeGrid() {
    if (this.grid) {
      this.scene.remove(this.grid);
      this.grid.geometry.dispose();
    }
    const box = this.geometry.boundingBox;
    const size = box.getSize(new THREE.Vector3());
    const center = box.getCenter(new THREE.Vector3());
    const extent = Math.max(size.x, size.z, size.y) * 2.2;
    this.grid = new THREE.GridHelper(extent, 16, 0x4f5661, 0x3a4049);
    this.grid.material.transparent = true;
    this.grid.material.opacity = 0.45;
    this.grid.material.depthWrite = false;
    this.grid.position.set(center.x, box.min.y - 0.002 * extent, center.z);
    this.grid.raycast = () => {};
    this.scene.add(this.grid);
  }

  /** Frame the whole mesh. */
  fit() {
    if (!this.geometry) return;
    const s = this.geometry.boundingSphere; // kept up to date by every position change
    this.radius = Math.max(s.radius, 1e-6);
    const fov = THREE.MathUtils.degToRad(this.camera.fov);
    const fitH = this.radius / Math.sin(fov / 2);
    const fitW = this.radius / Math.sin(Math.atan(Math.tan(fov / 2) * this.camera.aspect));
    const dist = Math.max(fitH, fitW) * 1.3;
    const dir = new THREE.Vector3(0.35, 0.28, 1).normalize();
    this.camera.position.copy(s.center).addScaledVector(dir, dist);
    this.camera.near = dist / 100;
    this.camera.far = dist * 100;
    this.camera.updateProjectionMatrix();
    if (this.controls) {
      this.controls.target.copy(s.center);
      this.controls.update();
    } else {
      this.camera.lookAt(s.center);
    }
    this.requestRender();
  }

  /** World units per CSS pixel at distance `point` from the camera. */
  worldPerPixel(point) {
    const d = this.camera.position.distanceTo(point);
    const h = this.canvas.clientHeight || 1;
    return (2 * d * Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2)) / h;
  }

  /** CSS pixel coordinates (relative to the canvas) of a world point. */
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
