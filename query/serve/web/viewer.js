// The 3-D view of a shape: its surface (mesh or cloud), its MDBD balls and contact graph.
// Balls are one InstancedMesh (a click gives the ball's number); rendering happens on demand.
import * as THREE from "three";
import { OrbitControls } from "three/addons/OrbitControls.js";

const BALL = new THREE.Color(0x4c9bd6);
const FAINT = new THREE.Color(0xc8c8c8);
const HIT = new THREE.Color(0xd62728);
const SURFACE = 0xa7b1bc;
const FILL = 1.04; // camera distance over the one that makes the bounding ball touch the view

// The surface as a light veil over the balls, or solid and shaded when the balls are hidden.
function setSolid(surf, solid) {
  const m = surf.material;
  m.transparent = !solid;
  m.opacity = solid ? 1 : (surf.isPoints ? 0.6 : 0.35);
  if (surf.isPoints) m.size = surf.userData.size * (solid ? 2.5 : 1);
  m.depthWrite = solid;
  m.needsUpdate = true;
}

// Whether the browser draws WebGL: checked once, on one context that is released at once
// (a context per check makes the browser warn "Too many active WebGL contexts").
let webgl = null;
export function webglAvailable() {
  if (webgl !== null) return webgl;
  try {
    const c = document.createElement("canvas");
    const gl = c.getContext("webgl2") || c.getContext("webgl");
    webgl = !!gl;
    const lose = gl && gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
  } catch (e) {
    webgl = false;
  }
  return webgl;
}

// A ball around the balls and the surface's points, centred on their box: {centre, radius}.
function sphereOf(shape, surface) {
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  const points = surface ? (surface.kind === "mesh" ? surface.vertices : surface.points || []) : [];
  shape.centers.forEach((c, i) => {
    for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], c[k] - shape.radii[i]);
      hi[k] = Math.max(hi[k], c[k] + shape.radii[i]);
    }
  });
  for (const p of points) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
  if (!(lo[0] <= hi[0])) { const b = boundsOf(shape); return { centre: b.centre, radius: b.size / 2 }; }
  const centre = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
  let radius = 0;
  shape.centers.forEach((c, i) => { radius = Math.max(radius, centre.distanceTo(new THREE.Vector3(...c)) + shape.radii[i]); });
  for (const p of points) radius = Math.max(radius, centre.distanceTo(new THREE.Vector3(...p)));
  return { centre, radius: radius || 1 };
}

function boundsOf(shape) {
  const [lo, hi] = shape.bounds;
  const centre = new THREE.Vector3((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2);
  const size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) || 1;
  return { centre, size };
}

// The objects of one shape: {group, balls, graph, surface}.
export function buildShape(shape, surface, { highlight = null, faint = false } = {}) {
  const group = new THREE.Group();
  const n = shape.radii.length;
  const sphere = new THREE.SphereGeometry(1, 20, 14);
  const material = new THREE.MeshStandardMaterial({ roughness: 0.55, metalness: 0.05 });
  const balls = new THREE.InstancedMesh(sphere, material, Math.max(n, 1));
  balls.count = n;
  const m = new THREE.Matrix4();
  const hl = new Set(highlight || []);
  for (let i = 0; i < n; i++) {
    const [x, y, z] = shape.centers[i];
    const r = shape.radii[i];
    m.makeScale(r, r, r).setPosition(x, y, z);
    balls.setMatrixAt(i, m);
    balls.setColorAt(i, hl.has(i) ? HIT : (highlight || faint ? FAINT : BALL));
  }
  balls.instanceMatrix.needsUpdate = true;
  if (balls.instanceColor) balls.instanceColor.needsUpdate = true;
  balls.computeBoundingSphere();
  group.add(balls);

  const pos = new Float32Array(shape.edges.length * 6);
  shape.edges.forEach(([i, j], k) => {
    pos.set(shape.centers[i], 6 * k);
    pos.set(shape.centers[j], 6 * k + 3);
  });
  const lines = new THREE.BufferGeometry();
  lines.setAttribute("position", new THREE.BufferAttribute(pos, 3));
  const graph = new THREE.LineSegments(lines, new THREE.LineBasicMaterial({ color: 0x222222 }));
  graph.visible = false;
  group.add(graph);

  let surf = null;
  if (surface && surface.kind === "mesh") {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(surface.vertices.flat()), 3));
    g.setIndex(surface.faces.flat());
    g.computeVertexNormals();
    surf = new THREE.Mesh(g, new THREE.MeshStandardMaterial({
      color: SURFACE, roughness: 0.7, flatShading: true, side: THREE.DoubleSide,
    }));
  } else if (surface && surface.kind === "points") {
    const g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.BufferAttribute(new Float32Array(surface.points.flat()), 3));
    surf = new THREE.Points(g, new THREE.PointsMaterial({
      color: 0x666666, size: boundsOf(shape).size / 250, transparent: true, opacity: 0.6,
    }));
    surf.userData.size = surf.material.size;
  }
  if (surf) group.add(surf);
  return { group, balls, graph, surface: surf };
}

function lights(scene) {
  scene.add(new THREE.HemisphereLight(0xffffff, 0x888888, 1.6));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(1, -1.5, 2);
  scene.add(sun);
}

// The camera of the thumbnails (elevation 20°, azimuth -60°, z up).
const VIEW = new THREE.Vector3(0.47, -0.814, 0.342);

// Point the camera at the shape from the thumbnails' side, near enough that the bounding
// ball of its balls and surface just fills the view's narrower side.
function frame(camera, shape, surface = null) {
  const { centre, radius } = sphereOf(shape, surface);
  const half = THREE.MathUtils.degToRad(camera.fov / 2);
  const fit = Math.min(half, Math.atan(Math.tan(half) * camera.aspect));
  const distance = (FILL * radius) / Math.sin(fit);
  camera.near = radius / 100;
  camera.far = distance * 100;
  camera.up.set(0, 0, 1);
  camera.position.copy(centre).add(VIEW.clone().multiplyScalar(distance));
  camera.lookAt(centre);
  camera.updateProjectionMatrix();
  return centre;
}

// An interactive view in a container element; onPick(node, point) on a click on a ball.
export class Viewer {
  constructor(container, { onPick = null, onMiss = null } = {}) {
    this.container = container;
    this.onPick = onPick;
    this.onMiss = onMiss; // a click that hit nothing
    this.layers = { surface: true, balls: true, graph: false };
    this.current = null;
    if (!webglAvailable()) {
      container.innerHTML = '<div class="note">This browser cannot draw 3-D (no WebGL).</div>';
      this.renderer = null;
      return;
    }
    this.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    container.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xffffff);
    lights(this.scene);
    this.camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
    this.camera.up.set(0, 0, 1); // z up, as in the thumbnails (before the controls read it)
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.addEventListener("change", () => this.render());
    this.raycaster = new THREE.Raycaster();
    let down = null;
    const el = this.renderer.domElement;
    el.addEventListener("pointerdown", (e) => { down = [e.clientX, e.clientY]; });
    el.addEventListener("pointerup", (e) => {
      if (down && Math.hypot(e.clientX - down[0], e.clientY - down[1]) < 5) this.pick(e);
      down = null;
    });
    new ResizeObserver(() => this.resize()).observe(container);
    this.resize();
  }

  resize() {
    if (!this.renderer) return;
    const w = this.container.clientWidth || 300, h = this.container.clientHeight || 300;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  }

  show(shape, surface, options = {}) {
    if (!this.renderer) return;
    if (this.current) {
      this.scene.remove(this.current.group);
      this.current.group.traverse((o) => { if (o.geometry) o.geometry.dispose(); });
    }
    this.shape = shape;
    this.current = buildShape(shape, surface, options);
    this.scene.add(this.current.group);
    this.controls.target.copy(frame(this.camera, shape, surface));
    this.controls.update();
    this.apply();
  }

  highlight(nodes) {
    if (!this.current) return;
    const hl = new Set(nodes || []);
    for (let i = 0; i < this.shape.radii.length; i++) {
      this.current.balls.setColorAt(i, nodes ? (hl.has(i) ? HIT : FAINT) : BALL);
    }
    this.current.balls.instanceColor.needsUpdate = true;
    this.render();
  }

  setLayer(name, on) {
    this.layers[name] = on;
    this.apply();
  }

  apply() {
    if (!this.current) return;
    this.current.balls.visible = this.layers.balls;
    this.current.graph.visible = this.layers.graph;
    if (this.current.surface) {
      this.current.surface.visible = this.layers.surface;
      setSolid(this.current.surface, !this.layers.balls);
    }
    this.render();
  }

  render() {
    if (this.renderer) this.renderer.render(this.scene, this.camera);
  }

  pick(event) {
    if (!this.current || !this.onPick) return;
    const rect = this.renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(
      ((event.clientX - rect.left) / rect.width) * 2 - 1,
      -((event.clientY - rect.top) / rect.height) * 2 + 1,
    );
    this.raycaster.setFromCamera(ndc, this.camera);
    const targets = [this.current.balls];
    if (!this.layers.balls && this.current.surface) targets[0] = this.current.surface;
    const hit = this.raycaster.intersectObjects(targets, false)[0];
    if (!hit) {
      if (this.onMiss) this.onMiss();
      return;
    }
    const node = hit.instanceId !== undefined ? hit.instanceId : null;
    this.onPick(node, hit.point.toArray());
  }

  // Screen position (client pixels) of ball i's centre, for tests and tooltips.
  screenOf(i) {
    const rect = this.renderer.domElement.getBoundingClientRect();
    const v = new THREE.Vector3(...this.shape.centers[i]).project(this.camera);
    return [rect.left + ((v.x + 1) / 2) * rect.width, rect.top + ((1 - v.y) / 2) * rect.height];
  }
}

// One shared off-screen renderer draws small pictures of shapes with highlighted balls.
let shared = null;
export function snapshot(canvas, shape, highlight) {
  if (!webglAvailable()) return false;
  const size = 256;
  if (!shared) {
    shared = { renderer: new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true }) };
    shared.renderer.setSize(size, size, false);
    shared.camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
  }
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  lights(scene);
  const built = buildShape(shape, null, { highlight });
  scene.add(built.group);
  frame(shared.camera, shape);
  shared.renderer.render(scene, shared.camera);
  canvas.width = size;
  canvas.height = size;
  canvas.getContext("2d").drawImage(shared.renderer.domElement, 0, 0, size, size);
  built.group.traverse((o) => { if (o.geometry) o.geometry.dispose(); });
  return true;
}
