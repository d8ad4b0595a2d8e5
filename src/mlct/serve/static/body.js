// The skinned humanoid beside the skeleton: the motion on screen, downloaded as a GLB (the
// same file the GLB button gives, on the rig chosen under Download), loaded with three.js's
// GLTFLoader and posed at the skeleton view's frame, so both play in step.
// app.js owns the motion; this module only reads window.mlct.state (request, frame, motion).
import * as THREE from "three";
import { GLTFLoader } from "/static/three/loaders/GLTFLoader.js";
import { OrbitControls } from "/static/three/controls/OrbitControls.js";

const $ = (id) => document.getElementById(id);
const view = {
  renderer: null, scene: null, camera: null, controls: null,
  model: null, mixer: null, clip: null, helper: null,
  loadedFor: null, // the request and rig the model was loaded for
  loading: false,
};
// What the end-to-end test reads.
// current: the model shown is the one for the motion and rig on screen (no load pending).
window.mlctBody = { ready: false, bones: [], rig: "", frame: -1, loads: 0, current: false, shown: "" };

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
  view.scene.add(new THREE.GridHelper(8, 16, 0xbbbbbb, 0xdddddd));
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
    view.scene.add(view.helper);
    view.mixer = new THREE.AnimationMixer(view.model);
    view.clip = gltf.animations[0];
    view.mixer.clipAction(view.clip).play();
    const bones = [];
    view.model.traverse((node) => { if (node.isBone) bones.push(node.name); });
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
    view.mixer.setTime(Math.min(state.frame / state.motion.fps, view.clip.duration));
    window.mlctBody.frame = state.frame;
  }
  view.renderer.render(view.scene, view.camera);
}

// Every bone's world position at a time of the clip, as three.js computes it: the end-to-end
// test compares them with mlct's own reading of the same GLB.
window.mlctBody.positionsAt = (seconds) => {
  view.mixer.setTime(seconds);
  view.model.updateMatrixWorld(true);
  const out = {};
  const point = new THREE.Vector3();
  view.model.traverse((node) => { if (node.isBone) out[node.name] = node.getWorldPosition(point).toArray(); });
  return out;
};

setup();
window.mlctBody.ready = true;
tick();
