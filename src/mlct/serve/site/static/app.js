// The static site's page: the model runs here (model.js), three draws the skeleton, playback at
// the motion's fps, downloads written in the page. window.mlct is what the tests and
// bench/web_speed.py read: ready, model, lastMotion (plain arrays), timings, generate().
"use strict";

import * as THREE from "three";
import { OrbitControls } from "./vendor/OrbitControls.js";
import { MotionModel } from "./model.js";
import { motionJson, npyBytes } from "./motion.js";
import { bvhText } from "./bvh.js";
import { glbBytes } from "./glb.js";

const COLOURS = { left: 0x2563eb, right: 0xdc2626, centre: 0x374151 };
const EXAMPLES = ["a person walks forward at a brisk pace.", "a person jumps up and down.",
  "the woman waves the right hand back and forth two times.", "a person walks backward slowly.",
  "someone bows.", "a man kicks with his right leg.", "a person walks forward, then waves with the right hand.",
  "a person jogs in place while clapping.", "a person runs forward for 8 seconds."];

const $ = (id) => document.getElementById(id);
const state = { motion: null, frame: 0, clock: 0, last: null, playing: true, busy: false, speed: 1 };
window.mlct = { ready: false, model: null, lastMotion: null, timings: [], state };

// --- the 3D view -------------------------------------------------------------------------

const view = { renderer: null, scene: null, camera: null, controls: null, figure: null, bones: [], joints: [] };

function setupView() {
  const canvas = $("view");
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xffffff);
  scene.add(new THREE.GridHelper(20, 40, 0xcbd5e1, 0xe2e8f0));
  scene.add(new THREE.HemisphereLight(0xffffff, 0x94a3b8, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(2, 4, 3);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(38, 1, 0.05, 100);
  camera.position.set(2.6, 1.7, 3.6);
  const controls = new OrbitControls(camera, canvas);
  controls.target.set(0, 0.9, 0);
  controls.update();
  Object.assign(view, { renderer, scene, camera, controls });
  resize();
  window.addEventListener("resize", resize);
}

function resize() {
  const canvas = $("view");
  const { clientWidth: w, clientHeight: h } = canvas;
  view.renderer.setSize(w, h, false);
  view.camera.aspect = w / h;
  view.camera.updateProjectionMatrix();
}

const sideOf = (name) => (name.startsWith("left") ? "left" : name.startsWith("right") ? "right" : "centre");

// Bones as cylinders coloured by side, joints as small spheres (a larger head), the root's
// path on the floor. Meshes, not GL lines: lines are one pixel wide in WebGL.
const UP = new THREE.Vector3(0, 1, 0);

function buildSkeleton(motion) {
  if (view.figure) view.scene.remove(view.figure);
  const { joint_names: names, parents } = motion.skeleton;
  const figure = new THREE.Group();
  const cylinder = new THREE.CylinderGeometry(0.022, 0.022, 1, 10);
  const sphere = new THREE.SphereGeometry(1, 14, 10);
  const materials = Object.fromEntries(Object.entries(COLOURS).map(([side, colour]) =>
    [side, new THREE.MeshLambertMaterial({ color: colour })]));
  const bones = parents.map((p, c) => [p, c]).filter(([p]) => p >= 0).map(([p, c]) => {
    const mesh = new THREE.Mesh(cylinder, materials[sideOf(names[c])]);
    figure.add(mesh);
    return { p, c, mesh };
  });
  const joints = names.map((name) => {
    const mesh = new THREE.Mesh(sphere, name === "head" ? materials.centre : new THREE.MeshLambertMaterial({ color: 0x111827 }));
    mesh.scale.setScalar(name === "head" ? 0.085 : 0.03);
    figure.add(mesh);
    return mesh;
  });
  const J = names.length;
  const root = new Float32Array(motion.frames * 3);
  for (let t = 0; t < motion.frames; t++) root.set([motion.joints[t * J * 3], 0.003, motion.joints[t * J * 3 + 2]], 3 * t);
  const path = new THREE.BufferGeometry();
  path.setAttribute("position", new THREE.BufferAttribute(root, 3));
  figure.add(new THREE.Line(path, new THREE.LineBasicMaterial({ color: 0x818cf8 })));
  view.scene.add(figure);
  Object.assign(view, { figure, bones, joints });
  // look at the middle of the motion, from far enough to see its extent
  const [xs, zs] = [column(root, 0), column(root, 2)];
  const [x0, z0, x1, z1] = [Math.min(...xs), Math.min(...zs), Math.max(...xs), Math.max(...zs)];
  const span = Math.max(3.2, x1 - x0 + 1.5, z1 - z0 + 1.5);
  view.controls.target.set((x0 + x1) / 2, 0.85, (z0 + z1) / 2);
  view.camera.position.set((x0 + x1) / 2 + 0.55 * span, 0.3 * span + 0.9, (z0 + z1) / 2 + 0.9 * span);
  view.controls.update();
}

function column(flat, k) { const out = []; for (let i = k; i < flat.length; i += 3) out.push(flat[i]); return out; }

const a = new THREE.Vector3();
const b = new THREE.Vector3();

function drawFrame(index) {
  const motion = state.motion;
  const J = motion.skeleton.joint_names.length;
  const pose = motion.joints.subarray(index * J * 3, (index + 1) * J * 3);
  for (const { p, c, mesh } of view.bones) {
    a.fromArray(pose, 3 * p);
    b.fromArray(pose, 3 * c);
    mesh.position.addVectors(a, b).multiplyScalar(0.5);
    b.sub(a);
    mesh.scale.set(1, Math.max(b.length(), 1e-6), 1);
    mesh.quaternion.setFromUnitVectors(UP, b.normalize());
  }
  view.joints.forEach((mesh, j) => mesh.position.fromArray(pose, 3 * j));
  state.frame = index;
  $("scrub").value = String(index);
  const fps = motion.skeleton.fps;
  $("clock").textContent = `${(index / fps).toFixed(2)} / ${(motion.frames / fps).toFixed(2)} s`;
}

function tick(now) {
  requestAnimationFrame(tick);
  const motion = state.motion;
  if (motion && !state.busy) {
    if (state.playing && state.last !== null) state.clock += ((now - state.last) / 1000) * state.speed;
    const total = motion.frames / motion.skeleton.fps;
    state.clock %= total;
    const index = Math.min(motion.frames - 1, Math.floor(state.clock * motion.skeleton.fps));
    if (index !== state.frame) drawFrame(index);
  }
  state.last = now;
  view.controls.update();
  view.renderer.render(view.scene, view.camera);
}

function setPlaying(playing) {
  state.playing = playing;
  $("play").textContent = playing ? "Pause" : "Play";
}

// --- generating --------------------------------------------------------------------------

function showStatus(text, error = false) {
  $("status").textContent = text;
  $("status").classList.toggle("error", error);
}

function request() {
  const model = window.mlct.model;
  const seed = $("seed").value.trim();
  // frames null: the model picks the length from the text (MotionModel.defaultSeconds)
  const frames = $("auto-length").checked ? null : model.framesFor(Number($("seconds").value));
  return { text: $("prompt").value, frames, candidates: Number($("candidates").value),
    nfe: Number($("nfe").value), seed: seed === "" ? Math.floor(Math.random() * 1e6) : Number(seed) };
}

// The prompt's parts under the timeline, each as wide as its share of the clip (an arm action
// done during the others spans the whole clip); nothing for a one-part prompt.
function showParts(motion) {
  const row = $("parts");
  row.replaceChildren();
  if (motion.parts.length < 2) return;
  for (const part of motion.parts) {
    const span = document.createElement("span");
    span.textContent = part.arms ? `+ arms: ${part.text}` : part.text;
    span.title = `${part.text} · ${(part.frames / motion.skeleton.fps).toFixed(1)} s`;
    span.style.flex = part.arms ? "0 0 auto" : `${part.frames} 1 0`;
    if (part.arms) span.className = "arms";
    row.appendChild(span);
  }
}

// Generate (a request, or the form's) and show it; resolves to the motion.
async function generate(req = null) {
  const body = req ?? request();
  state.busy = true;
  $("generate").classList.add("busy");
  try {
    const motion = await window.mlct.model.generate(body);
    state.motion = motion;
    window.mlct.lastMotion = { text: motion.text, seed: motion.seed, nfe: motion.nfe, frames: motion.frames,
      candidates: motion.candidates, joints: Array.from(motion.joints), parts: motion.parts, seams: motion.seams,
      timing: motion.timing };
    window.mlct.timings.push(motion.timing);
    if (!req && $("auto-length").checked) { // show the length the text got
      $("seconds").value = String(motion.frames / motion.skeleton.fps);
      $("seconds-value").textContent = `auto · ${(motion.frames / motion.skeleton.fps).toFixed(1)} s`;
    }
    buildSkeleton(motion);
    state.clock = 0;
    drawFrame(0);
    $("scrub").max = String(motion.frames - 1);
    const t = motion.timing;
    const parts = motion.parts.length < 2 ? "" : ` · made as ${motion.parts.length} parts in turn: ` +
      motion.parts.map((p) => `“${p.text}” ${(p.frames / motion.skeleton.fps).toFixed(1)} s`).join(", then ");
    showParts(motion);
    const best = motion.candidates > 1 ? `, best of ${motion.candidates}` : "";
    showStatus(`“${motion.text}” · ${motion.frames} frames, ${motion.nfe} steps${best}, seed ${motion.seed}${parts}`);
    $("timing").textContent = `in this page: ${t.total_ms.toFixed(1)} ms (text ${t.text_ms.toFixed(1)},` +
      ` sampling ${t.sample_ms.toFixed(1)}, decoding + joints ${t.decode_ms.toFixed(1)}) · WASM, ${window.mlct.model.threads} thread(s)`;
    for (const id of ["play", "scrub", "dl-json", "dl-npy", "dl-bvh", "dl-glb", "dl-gif"]) $(id).disabled = false;
    return motion;
  } catch (error) {
    showStatus(error.message, true);
    throw error;
  } finally {
    state.busy = false;
    state.last = null;
    $("generate").classList.remove("busy");
  }
}

// --- downloads: format -> (motion) => [bytes or string, MIME type, extension] -----------
const DOWNLOADS = {
  json: (m) => [JSON.stringify(motionJson(m)) + "\n", "application/json", "json"],
  npy: (m) => [npyBytes(m.joints, [m.frames, m.skeleton.joint_names.length, 3]), "application/octet-stream", "npy"],
  bvh: (m) => [bvhText(m), "application/octet-stream", "bvh"], // rotations fitted in bvh.js
  glb: async (m) => [await glbBytes(m), "model/gltf-binary", "glb"], // the same fit, three's GLTFExporter
  gif: async (m) => [await gifBytes(m), "image/gif", "gif"], // the view, every frame (gifenc)
};

// An animated GIF of the view as it is (camera, size), every frame at the motion's fps, 480
// pixels wide, one palette for the whole clip (as `mlct generate --out x.gif` makes one): the
// frames are drawn and read back in one go, then encoded by gifenc (vendor/, pinned).
const GIF_WIDTH = 480;
async function gifBytes(motion) {
  const { GIFEncoder, quantize, applyPalette } = await import("./vendor/gifenc.esm.js");
  const source = view.renderer.domElement;
  const canvas = document.createElement("canvas");
  canvas.width = GIF_WIDTH;
  canvas.height = Math.max(1, Math.round((GIF_WIDTH * source.height) / source.width));
  const context = canvas.getContext("2d", { willReadFrequently: true });
  const shown = state.frame;
  const pixels = [];
  for (let t = 0; t < motion.frames; t++) { // synchronous: playback does not run in between
    drawFrame(t);
    view.renderer.render(view.scene, view.camera);
    context.drawImage(source, 0, 0, canvas.width, canvas.height);
    pixels.push(context.getImageData(0, 0, canvas.width, canvas.height).data);
  }
  drawFrame(shown);
  // the palette from every 10th frame together: the figure's colours in all its poses
  const sample = new Uint8ClampedArray(Math.ceil(motion.frames / 10) * pixels[0].length);
  for (let t = 0; t < motion.frames; t += 10) sample.set(pixels[t], (t / 10) * pixels[0].length);
  const palette = quantize(sample, 256);
  const gif = GIFEncoder();
  const delay = 1000 / motion.skeleton.fps; // 50 ms at 20 fps, exact in 1/100 s
  pixels.forEach((rgba, t) => {
    gif.writeFrame(applyPalette(rgba, palette), canvas.width, canvas.height,
      t === 0 ? { palette, delay, repeat: 0 } : { delay });
  });
  gif.finish();
  return gif.bytes();
}

function fileName(motion, ext) {
  const slug = motion.text.toLowerCase().replace(/[^a-z0-9]+/g, "_").replace(/^_|_$/g, "").slice(0, 40) || "motion";
  return `${slug}_seed${motion.seed}.${ext}`;
}

async function download(format) {
  const motion = state.motion;
  if (!motion || !DOWNLOADS[format]) return;
  const [data, type, ext] = await DOWNLOADS[format](motion);
  const link = document.createElement("a");
  link.href = URL.createObjectURL(new Blob([data], { type }));
  link.download = fileName(motion, ext);
  document.body.appendChild(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(link.href), 60000);
}

// --- start -------------------------------------------------------------------------------

function bind() {
  $("prompt-form").addEventListener("submit", (event) => { event.preventDefault(); generate().catch(() => {}); });
  $("play").addEventListener("click", () => setPlaying(!state.playing));
  $("speed").addEventListener("change", () => { state.speed = Number($("speed").value); });
  $("scrub").addEventListener("input", () => {
    const index = Number($("scrub").value);
    state.clock = index / state.motion.skeleton.fps;
    setPlaying(false);
    drawFrame(index);
  });
  const echo = () => {
    const seconds = `${Number($("seconds").value).toFixed(1)} s`;
    $("seconds-value").textContent = $("auto-length").checked ? "auto" : seconds;
    $("nfe-value").textContent = $("nfe").value;
    $("candidates-value").textContent = $("candidates").value;
  };
  $("seconds").addEventListener("input", () => { $("auto-length").checked = false; echo(); });
  $("auto-length").addEventListener("change", echo);
  $("nfe").addEventListener("input", echo);
  $("candidates").addEventListener("input", echo);
  echo();
  $("dice").addEventListener("click", () => { $("seed").value = String(Math.floor(Math.random() * 1e6)); generate().catch(() => {}); });
  for (const button of document.querySelectorAll("#downloads button")) {
    button.addEventListener("click", () => download(button.dataset.format).catch((error) => showStatus(`the download failed: ${error.message}`, true)));
  }
  document.addEventListener("keydown", (event) => {
    if (event.code === "Space" && state.motion && event.target.tagName !== "INPUT") {
      event.preventDefault();
      setPlaying(!state.playing);
    }
  });
  for (const text of EXAMPLES) {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = text;
    button.addEventListener("click", () => { $("prompt").value = text; generate().catch(() => {}); });
    $("gallery").appendChild(button);
  }
}

// Threads: ?threads=N, else all cores (up to 4) where the page is cross-origin isolated (the
// server sends COOP/COEP headers: SharedArrayBuffer), else 1.
function threads() {
  const asked = Number(new URLSearchParams(location.search).get("threads"));
  if (asked >= 1) return Math.floor(asked);
  return window.crossOriginIsolated ? Math.min(4, navigator.hardwareConcurrency || 1) : 1;
}

window.addEventListener("DOMContentLoaded", async () => {
  bind();
  setupView();
  requestAnimationFrame(tick);
  try {
    const model = await MotionModel.load(new URL(".", location.href).href, { threads: threads() });
    window.mlct.model = model;
    window.mlct.generate = (req) => generate(req);
    const c = model.config;
    $("model-info").textContent = `${c.sampler.name} model · ${c.skeleton.name} · ${c.skeleton.fps} fps · ` +
      `up to ${(c.max_frames / c.skeleton.fps).toFixed(1)} s (a gait longer) · WASM, ${model.threads} thread(s)`;
    // a gait keeps going past the model's window (keepgoing.js): the slider reaches 30 s
    $("seconds").max = String(Math.min(30, model.longestGait / c.skeleton.fps));
    $("nfe").max = String(Math.min(10, c.sampler.max_nfe));
    $("nfe").value = String(c.sampler.default_nfe);
    // best of N: the model's default (8 for the bundled model, as mlct generate); 1 without a critic
    $("candidates").max = String(c.critic ? Math.min(16, c.critic.max_candidates) : 1);
    $("candidates").value = String(model.defaultCandidates);
    $("candidates").disabled = !c.critic;
    $("candidates-value").textContent = $("candidates").value;
    $("prompt").maxLength = c.max_prompt_chars;
    $("generate").disabled = false;
    await generate(); // something moves from the start
  } catch (error) {
    showStatus(`the model did not load: ${error.message}`, true);
  }
  window.mlct.ready = true;
});
