// The skinned humanoid beside the skeleton: the motion on screen, downloaded as a GLB (the
// same file the GLB button gives, on the rig chosen under Download), loaded with three.js's
// GLTFLoader and posed at the skeleton view's frame, so both play in step.
// app.js owns the motion; this module only reads window.mlct.state (request, frame, motion).
import * as THREE from "three";
import { GLTFLoader } from "/static/three/loaders/GLTFLoader.js";
import { OrbitControls } from "/static/three/controls/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const view = {
  renderer: null, scene: null, camera: null, controls: null, grid: null,
  model: null, mixer: null, clip: null, helper: null, root: null,
  path: null, // the root's smoothed floor position at each key of the clip (followPath)
  shift: new THREE.Vector3(), // how far the camera and its orbit target have been carried
  loadedFor: null, // the request and rig the model was loaded for
  loading: false,
};
// What the end-to-end test reads.
// current: the model shown is the one for the motion and rig on screen (no load pending).
// follow: the camera goes along with the character (false: it stays where the user put it).
window.mlctBody = {
  ready: false, bones: [], rig: "", frame: -1, loads: 0, current: false, shown: "", follow: true,
};

const GRID_CELL = 0.5; // metres
// Half the width of the box filter the followed path is smoothed with, run twice (a triangle
// twice as wide): about a stride, so the pelvis's sway from foot to foot and its bob are not
// passed to the camera, while a walk's steady pace is, without lag (the filter is centred).
const FOLLOW_HALF_SECONDS = 0.5;

function setup() {
  const box = $("body3d");
  view.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  view.renderer.setPixelRatio(window.devicePixelRatio);
  view.renderer.setSize(box.clientWidth, box.clientHeight);
  box.appendChild(view.renderer.domElement);
  view.scene = new THREE.Scene();
  view.scene.background = new THREE.Color(0xf7f7f8);
  view.camera = new THREE.PerspectiveCamera(35, box.clientWidth / box.clientHeight, 0.05, 100);
  view.camera.position.set(2.6, 1.6, 3.4);
  view.controls = new OrbitControls(view.camera, view.renderer.domElement);
  view.controls.target.set(0, 0.9, 0);
  view.controls.update();
  view.scene.add(new THREE.HemisphereLight(0xffffff, 0x8d8d8d, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(3, 6, 4);
  view.scene.add(sun);
  // one colour for every line: the grid is moved under the character a whole cell at a time
  // (follow), so a darker centre line would jump; the lines themselves stay put on the floor
  view.grid = new THREE.GridHelper(8, 8 / GRID_CELL, 0xdddddd, 0xdddddd);
  view.scene.add(view.grid);
  new ResizeObserver(() => {
    view.renderer.setSize(box.clientWidth, box.clientHeight);
    view.camera.aspect = box.clientWidth / box.clientHeight;
    view.camera.updateProjectionMatrix();
  }).observe(box);
}

async function load(request, rig) {
  view.loading = true;
  try {
    const body = { ...request, format: "glb", ...(rig ? { rig } : {}) };
    const response = await fetch("/generate", {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
    if (!response.ok) throw new Error(`GLB: HTTP ${response.status}`);
    const gltf = await new GLTFLoader().parseAsync(await response.arrayBuffer(), "");
    if (view.model) {
      view.scene.remove(view.model, view.helper);
      view.helper.dispose();
    }
    view.model = gltf.scene;
    view.scene.add(view.model);
    view.helper = new THREE.SkeletonHelper(view.model);
    view.helper.frustumCulled = false; // as the body's mesh, below
    view.scene.add(view.helper);
    view.mixer = new THREE.AnimationMixer(view.model);
    view.clip = gltf.animations[0];
    view.mixer.clipAction(view.clip).play();
    const bones = [];
    view.model.traverse((node) => {
      if (node.isBone) bones.push(node.name);
      // three keeps a skinned mesh's bounding sphere (and the skeleton lines') from where it
      // was first computed: once the camera has followed the walk away from there and the user
      // turns the view, the body would be culled out of it
      if (node.isSkinnedMesh) node.frustumCulled = false;
    });
    view.root = view.model.getObjectByName(bones[0]);
    view.path = followPath();
    window.mlctBody.bones = bones;
    window.mlctBody.rig = rig || "mlct";
    window.mlctBody.loads += 1;
    $("body-caption").textContent = `${rig || "mlct"} rig · ${bones.length} bones: ` +
      bones.slice(0, 4).join(", ") + ", …";
  } catch (error) {
    $("body-caption").textContent = `the humanoid did not load (${error.message})`;
  } finally {
    view.loading = false;
  }
}

// A time of the clip for the mixer: the clip's last key is at its duration, where the looping
// action has already wrapped round to its first pose, so the last frame is asked for a hair
// before it.
function clipTime(seconds) {
  return Math.min(seconds, view.clip.duration * (1 - 1e-6));
}

// The root's floor position (x, z) at every key of the clip, smoothed: where the camera is
// carried to. The camera and the character then step together, frame for frame (a chase with
// a lag of its own would show the character drifting in the view), and a frame always has the
// same view, whether played, scrubbed or looped.
function followPath() {
  const times = view.clip.tracks[0].times; // every track is keyed at every frame
  const n = times.length;
  let x = new Float64Array(n);
  let z = new Float64Array(n);
  const point = new THREE.Vector3();
  for (let i = 0; i < n; i++) {
    view.mixer.setTime(clipTime(times[i]));
    view.model.updateMatrixWorld(true);
    view.root.getWorldPosition(point);
    x[i] = point.x;
    z[i] = point.z;
  }
  const rate = n > 1 ? (n - 1) / times[n - 1] : 1;
  const half = Math.round(FOLLOW_HALF_SECONDS * rate);
  for (let pass = 0; pass < 2; pass++) [x, z] = [boxFilter(x, half), boxFilter(z, half)];
  return { x, z, rate };
}

// A moving average over 2 * half + 1 values, the ends held beyond the clip.
function boxFilter(values, half) {
  const n = values.length;
  const out = new Float64Array(n);
  for (let i = 0; i < n; i++) {
    let sum = 0;
    for (let k = i - half; k <= i + half; k++) sum += values[Math.min(n - 1, Math.max(0, k))];
    out[i] = sum / (2 * half + 1);
  }
  return out;
}

// Carries the camera and its orbit target together to the followed path at this time (or back
// to where the user left them, follow off): the user's orbit, zoom and pan are kept, and only
// the horizontal moves, so the view does not bob with the steps.
function follow(seconds) {
  const wanted = new THREE.Vector3();
  if (window.mlctBody.follow && view.path) {
    const { x, z, rate } = view.path;
    const i = Math.min(x.length - 1, Math.max(0, Math.round(seconds * rate)));
    wanted.set(x[i], 0, z[i]);
  }
  const step = wanted.clone().sub(view.shift);
  if (step.lengthSq() === 0) return;
  view.camera.position.add(step);
  view.controls.target.add(step);
  view.controls.update();
  view.shift.copy(wanted);
  // the floor goes along in whole cells, so its lines stay where they are on the ground
  view.grid.position.set(Math.round(wanted.x / GRID_CELL) * GRID_CELL, 0,
    Math.round(wanted.z / GRID_CELL) * GRID_CELL);
}

function tick() {
  requestAnimationFrame(tick);
  const { state } = window.mlct || {};
  if (state && state.request && !view.loading) {
    const rig = $("rig") ? $("rig").value : "";
    const wanted = `${JSON.stringify(state.request)}|${rig}`;
    if (wanted !== view.loadedFor) {
      view.loadedFor = wanted;
      window.mlctBody.current = false;
      load(state.request, rig).then(() => {
        window.mlctBody.current = view.loadedFor === wanted;
        if (window.mlctBody.current) window.mlctBody.shown = wanted; // which request and rig
      });
    }
  }
  if (view.mixer && state && state.motion && state.frame >= 0) {
    // the skeleton view's frame, not a clock of our own: both show the same instant
    const seconds = clipTime(state.frame / state.motion.fps);
    view.mixer.setTime(seconds);
    follow(seconds);
    window.mlctBody.frame = state.frame;
  }
  view.renderer.render(view.scene, view.camera);
}

// Every bone's world position at a time of the clip, as three.js computes it: the end-to-end
// test compares them with mlct's own reading of the same GLB.
window.mlctBody.positionsAt = (seconds) => {
  view.mixer.setTime(clipTime(seconds));
  view.model.updateMatrixWorld(true);
  const out = {};
  const point = new THREE.Vector3();
  view.model.traverse((node) => { if (node.isBone) out[node.name] = node.getWorldPosition(point).toArray(); });
  return out;
};

// Where the bones are drawn now: each bone's pixel in the panel (from its top left corner), as
// the camera projects it, with the panel's size, the root's world position and the camera's.
// The end-to-end test checks with it that the character stays in view as it travels.
window.mlctBody.onScreen = () => {
  const { clientWidth: width, clientHeight: height } = view.renderer.domElement;
  view.model.updateMatrixWorld(true);
  view.camera.updateMatrixWorld();
  const pixels = {};
  const point = new THREE.Vector3();
  view.model.traverse((node) => {
    if (!node.isBone) return;
    node.getWorldPosition(point).project(view.camera);
    pixels[node.name] = [(point.x + 1) / 2 * width, (1 - point.y) / 2 * height];
  });
  return { pixels, width, height, root: view.root.getWorldPosition(point).toArray(),
    camera: view.camera.position.toArray(), target: view.controls.target.toArray() };
};

setup();
window.mlctBody.ready = true;
tick();
