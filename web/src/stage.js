// The fixed furniture of the viewer's scene: the lights, which ride with the camera so that the side facing the
// viewer is always lit, the floor grid under the mesh, which gives a sense of scale and of up, and the camera's
// framing of the whole mesh. None depends on the mesh's roles or shape beyond its bounds, so they live apart from
// the viewer that draws and updates the mesh.
import * as THREE from 'three';

/**
 * Light the scene: a hemisphere light, and three directional lights added to the camera so that they follow it.
 * @param {THREE.Scene} scene
 * @param {THREE.Camera} camera
 */
export function addLights(scene, camera) {
  scene.add(new THREE.HemisphereLight(0xeef2ff, 0x2a2622, 0.55));
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
    camera.add(light, light.target);
  }
}

/**
 * A faint grid on the floor under a mesh of bounds `box`, a little wider than the mesh; rays pass through it. The
 * floor is across the up axis: the xz plane for Y up, the xy plane for Z up.
 * @param {THREE.Box3} box
 * @param {'y'|'z'} [up]
 */
export function floorGrid(box, up = 'y') {
  const size = box.getSize(new THREE.Vector3());
  const center = box.getCenter(new THREE.Vector3());
  const extent = Math.max(size.x, size.z, size.y) * 2.2;
  const grid = new THREE.GridHelper(extent, 16, 0x4f5661, 0x3a4049);
  grid.material.transparent = true;
  grid.material.opacity = 0.45;
  grid.material.depthWrite = false;
  if (up === 'z') {
    grid.rotation.x = Math.PI / 2;
    grid.position.set(center.x, center.y, box.min.z - 0.002 * extent);
  } else {
    grid.position.set(center.x, box.min.y - 0.002 * extent, center.z);
  }
  grid.raycast = () => {};
  return grid;
}

/**
 * Point the camera at a sphere from a little above and to the right, far enough for all of it to show, and aim the
 * orbit controls (when given) at its centre. The radius framed (at least 1e-6) is returned.
 * @param {THREE.PerspectiveCamera} camera
 * @param {import('three/addons/controls/OrbitControls.js').OrbitControls|null} controls
 * @param {THREE.Sphere} sphere
 */
export function frameSphere(camera, controls, sphere) {
  const radius = Math.max(sphere.radius, 1e-6);
  const fov = THREE.MathUtils.degToRad(camera.fov);
  const fitH = radius / Math.sin(fov / 2);
  const fitW = radius / Math.sin(Math.atan(Math.tan(fov / 2) * camera.aspect));
  const dist = Math.max(fitH, fitW) * 1.3;
  // from the front (+z for Y up, -y for Z up), a little above and to the right
  const dir = (camera.up.z > 0.5 ? new THREE.Vector3(0.35, -1, 0.28) : new THREE.Vector3(0.35, 0.28, 1)).normalize();
  camera.position.copy(sphere.center).addScaledVector(dir, dist);
  camera.near = dist / 100;
  camera.far = dist * 100;
  camera.updateProjectionMatrix();
  if (controls) {
    controls.target.copy(sphere.center);
    controls.update();
  } else {
    camera.lookAt(sphere.center);
  }
  return radius;
}
