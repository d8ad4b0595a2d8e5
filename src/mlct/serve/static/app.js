// The mlct web page: prompt -> POST /generate -> a plotly scatter3d skeleton played at the
// motion's fps. Data are y-up; plotly's scene is z-up, so a point (x, y, z) is drawn at
// (x, -z, y), a rotation (not a mirror: left stays left).
"use strict";

const SIDE_COLOURS = { left: "#2563eb", right: "#dc2626", centre: "#374151" };
const TRACE = { floor: 0, path: 1, left: 2, right: 3, centre: 4, joints: 5 };
const MIN_SPAN = 2.0; // metres of floor shown around the motion, at least

const $ = (id) => document.getElementById(id);
const state = {
  motion: null, // the last motion (motion_json + seed, nfe)
  frames: null, // per frame: {left, right, centre, joints} as {x, y, z} arrays for plotly
  request: null, // the body that made it (downloads repeat it with a format)
  frame: -1, clock: 0, last: null, playing: true, speed: 1, drawing: false,
  waiting: 0, // generations in flight: playback holds still and leaves the CPU to them
};
// What the end-to-end test and the latency figures read.
window.mlct = { state, firstFrameMs: [], framesDrawn: 0, ready: false };

// --- geometry ----------------------------------------------------------------------------

function sideOf(name) {
  if (name.startsWith("left")) return "left";
  if (name.startsWith("right")) return "right";
  return "centre";
}

// Bones grouped by side: [parent, child] pairs, a bone's side being its child's.
function boneGroups(motion) {
  const groups = { left: [], right: [], centre: [] };
  motion.parents.forEach((parent, child) => {
    if (parent >= 0) groups[sideOf(motion.joint_names[child])].push([parent, child]);
  });
  return groups;
}

// Plotly coordinates of every frame, computed once so that playback only restyles.
function prepare(motion) {
  const scale = motion.unit === "mm" ? 0.001 : 1;
  const groups = boneGroups(motion);
  const point = (p) => [p[0] * scale, -p[2] * scale, p[1] * scale];
  const lo = [Infinity, Infinity, 0];
  const hi = [-Infinity, -Infinity, 0];
  const frames = motion.joints.map((pose) => {
    const pts = pose.map(point);
    for (const p of pts) {
      for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
    }
    const frame = { joints: { x: pts.map((p) => p[0]), y: pts.map((p) => p[1]), z: pts.map((p) => p[2]) } };
    for (const [side, bones] of Object.entries(groups)) {
      const line = { x: [], y: [], z: [] };
      for (const [a, b] of bones) {
        for (const [axis, k] of [["x", 0], ["y", 1], ["z", 2]]) line[axis].push(pts[a][k], pts[b][k], null);
      }
      frame[side] = line;
    }
    return frame;
  });
  const root = motion.joints.map((pose) => point(pose[0]));
  return { frames, root, bounds: box(lo, hi), head: motion.joint_names.indexOf("head") };
}

// Axis ranges with equal scale: the motion's extent, at least MIN_SPAN, floor at z = 0.
function box(lo, hi) {
  const pad = 0.3;
  const span = Math.max(MIN_SPAN, hi[0] - lo[0] + 2 * pad, hi[1] - lo[1] + 2 * pad);
  const mid = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2];
  const top = Math.max(hi[2] + 0.15, 1.9);
  return { x: [mid[0] - span / 2, mid[0] + span / 2], y: [mid[1] - span / 2, mid[1] + span / 2],
           z: [Math.min(lo[2], 0) - 0.01, top], span };
}

function floorGrid(bounds, step = 0.5) {
  const line = { x: [], y: [], z: [] };
  const push = (x0, y0, x1, y1) => { line.x.push(x0, x1, null); line.y.push(y0, y1, null); line.z.push(0, 0, null); };
  const [x0, x1] = bounds.x;
  const [y0, y1] = bounds.y;
  for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) push(x, y0, x, y1);
  for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) push(x0, y, x1, y);
  return line;
}

// --- the plot ----------------------------------------------------------------------------

function traces(prepared) {
  const first = prepared.frames[0];
  const grid = floorGrid(prepared.bounds);
  const lines = (side) => ({ type: "scatter3d", mode: "lines", hoverinfo: "skip", name: side,
    ...first[side], line: { color: SIDE_COLOURS[side], width: 7 } });
  const joints = first.joints.x.map((_, j) => (j === prepared.head ? 9 : 4)); // a larger head
  return [
    { type: "scatter3d", mode: "lines", hoverinfo: "skip", ...grid, line: { color: "#d5d9e0", width: 2 } },
    { type: "scatter3d", mode: "lines", hoverinfo: "skip", x: prepared.root.map((p) => p[0]),
      y: prepared.root.map((p) => p[1]), z: prepared.root.map(() => 0),
      line: { color: "#a5b4fc", width: 4 } },
    lines("left"), lines("right"), lines("centre"),
    { type: "scatter3d", mode: "markers", hoverinfo: "skip", ...first.joints,
      marker: { size: joints, color: "#111827" } },
  ];
}

function layout(bounds) {
  const axis = (range) => ({ range, visible: false, autorange: false });
  const [dx, dy, dz] = [bounds.x, bounds.y, bounds.z].map((r) => r[1] - r[0]);
  const m = Math.max(dx, dy, dz);
  return {
    margin: { l: 0, r: 0, t: 0, b: 0 }, showlegend: false, paper_bgcolor: "#ffffff",
    uirevision: "keep", // the user's camera survives new motions
    scene: {
      xaxis: axis(bounds.x), yaxis: axis(bounds.y), zaxis: axis(bounds.z),
      aspectmode: "manual", aspectratio: { x: dx / m, y: dy / m, z: dz / m },
      camera: { eye: { x: 0.9, y: -1.35, z: 0.55 }, up: { x: 0, y: 0, z: 1 },
                center: { x: 0, y: 0, z: -0.1 } },
      dragmode: "turntable",
    },
  };
}

const CONFIG = { displaylogo: false, responsive: true,
                 modeBarButtonsToRemove: ["toImage", "resetCameraLastSave3d"] };

function drawFrame(index) {
  const frame = state.frames.frames[index];
  const sides = ["left", "right", "centre", "joints"];
  state.frame = index;
  state.drawing = true;
  return Plotly.restyle("plot", {
    x: sides.map((s) => frame[s].x), y: sides.map((s) => frame[s].y), z: sides.map((s) => frame[s].z),
  }, [TRACE.left, TRACE.right, TRACE.centre, TRACE.joints]).then(() => {
    state.drawing = false;
    window.mlct.framesDrawn += 1;
    updateClock();
  });
}

// --- playback ----------------------------------------------------------------------------

function tick(now) {
  requestAnimationFrame(tick);
  const motion = state.motion;
  if (!motion || state.waiting > 0) return;
  if (state.playing && state.last !== null) state.clock += ((now - state.last) / 1000) * state.speed;
  state.last = now;
  const total = motion.frames / motion.fps;
  state.clock %= total;
  const index = Math.min(motion.frames - 1, Math.floor(state.clock * motion.fps));
  if (index !== state.frame && !state.drawing) drawFrame(index);
}

function updateClock() {
  const motion = state.motion;
  $("scrub").value = String(state.frame);
  $("clock").textContent = `${(state.frame / motion.fps).toFixed(2)} / ${(motion.frames / motion.fps).toFixed(2)} s`;
}

function setPlaying(playing) {
  state.playing = playing;
  $("play").textContent = playing ? "Pause" : "Play";
}

// --- requests ----------------------------------------------------------------------------

function requestBody() {
  const body = { text: $("prompt").value, nfe: Number($("nfe").value), candidates: Number($("candidates").value) };
  const seed = $("seed").value.trim();
  if (seed !== "") body.seed = Number(seed);
  const control = window.mlctControl && window.mlctControl.control(); // control.js: path, pins
  if (control) body.control = control;
  // without seconds the server gives the prompt generate()'s default length (5 s, or as long
  // as its actions take); a path or pins keep the slider's
  if (!$("auto-length").checked || control) body.seconds = Number($("seconds").value);
  return body;
}

async function postGenerate(body) {
  const headers = { "Content-Type": "application/json" };
  // A server started with --token: the page's URL carries it as #token=... (a fragment is never
  // sent to a server or written to its logs).
  const token = new URLSearchParams(location.hash.slice(1)).get("token");
  if (token) headers.Authorization = `Bearer ${token}`;
  const response = await fetch("/generate", { method: "POST", headers, body: JSON.stringify(body) });
  if (!response.ok) {
    let detail = `${response.status} ${response.statusText}`;
    try { detail = (await response.json()).detail || detail; } catch (_) { /* not JSON */ }
    throw new Error(detail);
  }
  return response;
}

function showStatus(html, error = false) {
  const status = $("status");
  status.innerHTML = html;
  status.classList.toggle("error", error);
}

// A prompt (or some of its actions) the model does not know: its motion is likely not what was
// asked, which the motion itself does not show (the server's unknown_parts).
function showUnknown(parts) {
  const note = $("unknown-note");
  note.hidden = !parts || parts.length === 0;
  note.textContent = note.hidden ? "" : `${parts.map((p) => `“${p}”`).join(" and ")} is far from` +
    " every caption the model was trained on (a few kinds of action): this motion may not be what was asked.";
}

function escapeHtml(text) {
  return text.replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));
}

async function generate() {
  const clicked = performance.now();
  const body = requestBody();
  $("generate").classList.add("busy");
  state.waiting += 1;
  try {
    const response = await postGenerate(body);
    const data = await response.json();
    const received = performance.now();
    const motion = data.motions[0];
    state.motion = motion;
    state.frames = prepare(motion);
    state.request = { text: motion.text, lengths: motion.frames, nfe: motion.nfe, seed: motion.seed };
    if (body.control) state.request.control = body.control;
    state.clock = 0;
    state.frame = 0;
    state.drawing = true; // the first frame is drawn here, not by tick
    $("scrub").max = String(motion.frames - 1);
    if (body.seconds === undefined) { // show the length the text got (the slider keeps its own)
      $("seconds-value").textContent = `auto · ${(motion.frames / motion.fps).toFixed(1)} s`;
    }
    updateClock();
    await Plotly.react("plot", traces(state.frames), layout(state.frames.bounds), CONFIG);
    // The next animation frame paints the new motion: that is click -> first frame.
    await new Promise((resolve) => requestAnimationFrame(resolve));
    const firstFrame = performance.now() - clicked;
    state.drawing = false;
    window.mlct.firstFrameMs.push(firstFrame);
    window.mlct.framesDrawn += 1;
    const t = data.timing;
    const best = motion.candidates > 1 ? ` best of ${motion.candidates},` : "";
    showStatus(`<b>${escapeHtml(motion.text)}</b> · ${motion.frames} frames, ${motion.nfe} steps,${best}` +
      ` seed ${motion.seed} · server <b>${t.server_ms.toFixed(0)} ms</b> (model` +
      ` ${t.generate_ms.toFixed(0)} ms, batch ${t.batch_size}) · round trip` +
      ` ${(received - clicked).toFixed(0)} ms · first frame <b>${firstFrame.toFixed(0)} ms</b>`);
    showUnknown(motion.unknown_parts);
    for (const id of ["play", "scrub", "dl-bvh", "dl-npy", "dl-gif", "dl-glb", "dl-fbx",
      "dl-vrma", "dl-npz"]) $(id).disabled = false;
  } catch (error) {
    showStatus(escapeHtml(error.message), true);
    showUnknown([]);
  } finally {
    $("generate").classList.remove("busy");
    state.waiting -= 1;
    state.last = null;
  }
}

async function download(format) {
  if (!state.request) return;
  const button = $(`dl-${format}`);
  button.disabled = true;
  try {
    // a rig preset renames and re-poses the skeleton of BVH, GLB and FBX files (docs/export.md)
    const rig = $("rig").value;
    const retarget = rig && ["bvh", "glb", "fbx"].includes(format) ? { rig } : {};
    const response = await postGenerate({ ...state.request, format, ...retarget });
    const blob = await response.blob();
    const match = /filename="([^"]+)"/.exec(response.headers.get("Content-Disposition") || "");
    const link = document.createElement("a");
    link.href = URL.createObjectURL(blob);
    link.download = match ? match[1] : `motion.${format}`;
    document.body.appendChild(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(link.href), 60000);
  } catch (error) {
    showStatus(escapeHtml(error.message), true);
  } finally {
    button.disabled = false;
  }
}

// --- start -------------------------------------------------------------------------------

async function loadInfo() {
  try {
    const health = await (await fetch("/health")).json();
    const { model, limits } = health;
    $("model-info").textContent = `${model.sampler} model · ${model.skeleton} · ${model.fps} fps` +
      ` · up to ${limits.max_seconds.toFixed(1)} s`;
    $("seconds").max = String(limits.max_seconds);
    $("nfe").max = String(Math.min(10, limits.max_nfe));
    // best of N: the model's default (8 for the bundled model); 1 without a critic
    $("candidates").max = String(Math.min(16, model.max_candidates ?? 1));
    $("candidates").value = String(model.candidates ?? 1);
    $("candidates").disabled = (model.max_candidates ?? 1) < 2;
    $("candidates-value").textContent = $("candidates").value;
    $("prompt").maxLength = limits.max_text_chars;
  } catch (_) {
    $("model-info").textContent = "the server did not answer /health";
  }
}

function bind() {
  $("prompt-form").addEventListener("submit", (event) => { event.preventDefault(); generate(); });
  $("play").addEventListener("click", () => setPlaying(!state.playing));
  $("scrub").addEventListener("input", () => {
    const index = Number($("scrub").value);
    state.clock = index / state.motion.fps;
    setPlaying(false);
    if (!state.drawing) drawFrame(index);
  });
  $("speed").addEventListener("change", () => { state.speed = Number($("speed").value); });
  const echo = () => {
    const seconds = `${Number($("seconds").value).toFixed(1)} s`;
    $("seconds-value").textContent = $("auto-length").checked ? "auto" : seconds;
    $("nfe-value").textContent = $("nfe").value;
    $("candidates-value").textContent = $("candidates").value;
  };
  $("seconds").addEventListener("input", () => { $("auto-length").checked = false; echo(); });
  $("auto-length").addEventListener("change", echo);
  $("candidates").addEventListener("input", echo);
  $("nfe").addEventListener("input", echo);
  echo();
  $("dice").addEventListener("click", () => { $("seed").value = String(Math.floor(Math.random() * 1e6)); generate(); });
  for (const button of document.querySelectorAll(".downloads button")) {
    button.addEventListener("click", () => download(button.dataset.format));
  }
  document.addEventListener("keydown", (event) => {
    if (event.code === "Space" && state.motion && event.target.tagName !== "INPUT") {
      event.preventDefault();
      setPlaying(!state.playing);
    }
  });
}

// The gallery: the server's example prompts (it encodes them at start, so they are fastest).
async function loadExamples() {
  const { examples } = await (await fetch("/examples")).json();
  for (const text of examples) {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = text;
    button.addEventListener("click", () => { $("prompt").value = text; generate(); });
    $("gallery").appendChild(button);
  }
}

window.addEventListener("DOMContentLoaded", async () => {
  bind();
  // An empty scene now, so the WebGL context exists before the first click.
  const empty = { frames: [], root: [], bounds: box([-1, -1, 0], [1, 1, 1.8]), head: -1 };
  const blank = { x: [], y: [], z: [] };
  empty.frames.push({ left: blank, right: blank, centre: blank, joints: blank });
  await Plotly.newPlot("plot", traces(empty), layout(empty.bounds), CONFIG);
  await Promise.all([loadInfo(), loadExamples()]);
  requestAnimationFrame(tick);
  await generate(); // something moves from the start (and WebGL has drawn a skeleton once)
  window.mlct.ready = true;
});
