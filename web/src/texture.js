// How a textured or coloured mesh file is drawn: the `appearance` message (render mesh, UVs, texture image, vertex
// colours) and the textured render mesh, whose vertices follow the solved mesh's through an index map.
import * as THREE from 'three';

/** The display modes of the surface, in the panel's order. */
export const SURFACES = /** @type {const} */ (['texture', 'colours', 'plain']);

/** How strongly a painted role colour covers the texture or the file's colours (0..1). */
export const ROLE_BLEND = 0.7;
/** How strongly the grey of vertices outside the region of interest covers them. */
export const OUTSIDE_BLEND = 0.55;

const srgbToLinear = (/** @type {number} */ c) => (c < 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4);

/**
 * @typedef {object} Look
 * @property {Uint32Array|null} map the mesh vertex each render vertex follows (null without a texture)
 * @property {Float32Array|null} uv 2 per render vertex, v down from the image's top row
 * @property {Uint32Array|null} faces render triangles
 * @property {Float32Array|null} colorsLinear 3 per mesh vertex (linear), or null
 * @property {Blob|null} texture the base-colour image
 * @property {string[]} notes what is not shown and why
 */

/**
 * The arrays of an `appearance` frame (copies: they outlive the frame).
 * @param {{header: any, payload: Uint8Array}} frame
 * @param {number} nVertices vertices of the mesh it belongs to
 * @returns {Look}
 */
export function appearanceArrays(frame, nVertices) {
  const h = frame.header;
  const p = frame.payload;
  const r = h.render_vertices | 0;
  const t = h.render_faces | 0;
  const copy = (/** @type {number} */ start, /** @type {number} */ bytes) => p.slice(start, start + bytes).buffer;
  let o = 0;
  let map = null, uv = null, faces = null;
  if (r > 0) {
    map = new Uint32Array(copy(o, 4 * r));
    o += 4 * r;
    uv = new Float32Array(copy(o, 8 * r));
    o += 8 * r;
    faces = new Uint32Array(copy(o, 12 * t));
    o += 12 * t;
  }
  let colorsLinear = null;
  if (h.colors) {
    const bytes = p.subarray(o, o + 3 * nVertices);
    const lut = new Float32Array(256);
    for (let k = 0; k < 256; k++) lut[k] = srgbToLinear(k / 255);
    colorsLinear = new Float32Array(3 * nVertices);
    for (let k = 0; k < bytes.length; k++) colorsLinear[k] = lut[bytes[k]];
    o += 3 * nVertices;
  }
  const n = h.texture_bytes | 0;
  const texture = n > 0 && r > 0 ? new Blob([p.slice(o, o + n)], { type: h.texture_mime || 'image/png' }) : null;
  return { map, uv, faces, colorsLinear, texture, notes: Array.isArray(h.notes) ? h.notes.map(String) : [] };
}

/**
 * What a textured render mesh is made of, or null when the look has no texture to show.
 * @param {Look} look
 * @returns {{map: Uint32Array, uv: Float32Array, faces: Uint32Array, texture: Blob}|null}
 */
export function textureParts(look) {
  const { map, uv, faces, texture } = look;
  return map && uv && faces && texture ? { map, uv, faces, texture } : null;
}

/**
 * A standard material drawing `map` with the per-vertex RGBA colour attribute mixed over it (alpha: how much of the
 * colour covers the texture), so painted roles stay readable on a textured surface.
 * @param {THREE.Texture} map
 */
export function blendedMaterial(map) {
  const m = new THREE.MeshStandardMaterial({
    map,
    vertexColors: true,
    roughness: 0.7,
    metalness: 0.0,
    side: THREE.DoubleSide,
    polygonOffset: true,
    polygonOffsetFactor: 1,
    polygonOffsetUnits: 1,
  });
  m.onBeforeCompile = (shader) => {
    shader.fragmentShader = shader.fragmentShader.replace('#include <color_fragment>',
      '#if defined( USE_COLOR_ALPHA )\n\tdiffuseColor.rgb = mix( diffuseColor.rgb, vColor.rgb, vColor.a );\n#endif');
  };
  m.customProgramCacheKey = () => 'arap-blended-texture';
  return m;
}

/** The textured render mesh: its geometry gathers positions and normals of the solved mesh through `map`. */
export class RenderMesh {
  /**
   * @param {{map: Uint32Array, uv: Float32Array, faces: Uint32Array, texture: Blob}} look (textureParts)
   * @param {() => void} redraw called once the texture image is decoded
   */
  constructor(look, redraw) {
    const r = look.map.length;
    this.map = look.map;
    /** The triangles as the appearance gave them (drawOrder reorders the index from them). */
    this.faces = look.faces.slice();
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * r), 3));
    g.setAttribute('normal', new THREE.BufferAttribute(new Float32Array(3 * r), 3));
    g.setAttribute('uv', new THREE.BufferAttribute(look.uv, 2));
    const tint = new Float32Array(4 * r); // alpha 0: the texture as it is
    g.setAttribute('color', new THREE.BufferAttribute(tint, 4));
    g.setIndex(new THREE.BufferAttribute(look.faces, 1));
    this.box = new THREE.Box3();
    this.sphere = new THREE.Sphere();
    g.boundingBox = this.box;
    g.boundingSphere = this.sphere;
    this.geometry = g;
    this.texture = new THREE.Texture();
    this.texture.flipY = false; // UVs count v down from the image's top row (glTF)
    this.texture.colorSpace = THREE.SRGBColorSpace;
    this.texture.wrapS = THREE.RepeatWrapping;
    this.texture.wrapT = THREE.RepeatWrapping;
    this.texture.anisotropy = 4;
    this.material = blendedMaterial(this.texture);
    this.mesh = new THREE.Mesh(g, this.material);
    this.mesh.raycast = () => {}; // picking uses the solved mesh
    this.ready = false;
    this.failed = false;
    const url = URL.createObjectURL(look.texture);
    const img = new Image();
    img.src = url;
    img.decode().then(() => {
      this.texture.image = img;
      this.texture.needsUpdate = true;
      this.ready = true;
      redraw();
    }, () => {
      this.failed = true;
      redraw();
    }).finally(() => URL.revokeObjectURL(url));
  }

  /**
   * Positions and normals of the solved mesh (3 per vertex) onto the render vertices: one gather per frame.
   * @param {ArrayLike<number>} positions
   * @param {ArrayLike<number>} normals
   * @param {THREE.Box3} box the solved mesh's bounds (shared)
   * @param {THREE.Sphere} sphere
   */
  follow(positions, normals, box, sphere) {
    const g = this.geometry;
    const pa = /** @type {THREE.BufferAttribute} */ (g.attributes.position);
    const na = /** @type {THREE.BufferAttribute} */ (g.attributes.normal);
    const p = pa.array, n = na.array, map = this.map;
    for (let k = 0, o = 0; k < map.length; k++, o += 3) {
      const i = 3 * map[k];
      p[o] = positions[i];
      p[o + 1] = positions[i + 1];
      p[o + 2] = positions[i + 2];
      n[o] = normals[i];
      n[o + 1] = normals[i + 1];
      n[o + 2] = normals[i + 2];
    }
    pa.needsUpdate = true;
    na.needsUpdate = true;
    this.box.copy(box);
    this.sphere.copy(sphere);
  }

  /**
   * The role tint of each solved vertex (RGBA, 4 per vertex) onto the render vertices.
   * @param {Float32Array} tint
   */
  tint(tint) {
    const attr = /** @type {THREE.BufferAttribute} */ (this.geometry.attributes.color);
    const c = attr.array, map = this.map;
    for (let k = 0, o = 0; k < map.length; k++, o += 4) {
      const i = 4 * map[k];
      c[o] = tint[i];
      c[o + 1] = tint[i + 1];
      c[o + 2] = tint[i + 2];
      c[o + 3] = tint[i + 3];
    }
    attr.needsUpdate = true;
  }

  /**
   * Draw the triangles in `order` (later over earlier where they overlap: a picture's pin depths), or as given (null).
   * @param {number[]|null|undefined} order a permutation of the triangles
   */
  drawOrder(order) {
    const index = /** @type {THREE.BufferAttribute} */ (this.geometry.index);
    const out = index.array, faces = this.faces, t = faces.length / 3;
    if (!order || order.length !== t) out.set(faces);
    else order.forEach((f, j) => out.set(faces.subarray(3 * f, 3 * f + 3), 3 * j));
    index.needsUpdate = true;
  }

  dispose() {
    this.geometry.dispose();
    this.material.dispose();
    this.texture.dispose();
  }
}
