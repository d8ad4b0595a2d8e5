// Controls on the web page (mlct.generate.control.schema's schema): draw the root's path on a top view
// of the floor with the mouse, and pin the pose on screen at its frame. app.js asks
// window.mlctControl.control() for the request's "control" field before each generation.
// The floor view: x to the right, z up the canvas (the 3D view's floor seen from above).
"use strict";

(() => {
  const HALF_SPAN = 3.0; // metres from the centre to each edge of the floor view
  const STEP = 0.3; // metres between the waypoints sent (the drawn line is resampled)
  const MAX_WAYPOINTS = 24;
  const WALK_PACE = 0.45; // m/s: the length slider grows to walk a drawn path at this pace
  const cs = { drawn: [], pins: [], drawing: false };
  const $ = (id) => document.getElementById(id);

  function toFloor(canvas, event) {
    const box = canvas.getBoundingClientRect();
    const u = (event.clientX - box.left) / box.width;
    const v = (event.clientY - box.top) / box.height;
    return [(u * 2 - 1) * HALF_SPAN, (1 - v * 2) * HALF_SPAN];
  }

  function toCanvas(canvas, [x, z]) {
    return [((x / HALF_SPAN + 1) / 2) * canvas.width, ((1 - z / HALF_SPAN) / 2) * canvas.height];
  }

  // The drawn line resampled every STEP metres (at most MAX_WAYPOINTS points): [[x, z], ...].
  function waypoints() {
    const pts = cs.drawn;
    if (pts.length < 2) return [];
    const along = [0];
    for (let i = 1; i < pts.length; i++) {
      along.push(along[i - 1] + Math.hypot(pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1]));
    }
    const total = along[along.length - 1];
    if (total < 0.05) return [];
    const count = Math.min(MAX_WAYPOINTS, Math.max(2, Math.round(total / STEP) + 1));
    const out = [];
    let k = 0;
    for (let n = 0; n < count; n++) {
      const s = (total * n) / (count - 1);
      while (k < pts.length - 2 && along[k + 1] < s) k++;
      const w = (s - along[k]) / Math.max(along[k + 1] - along[k], 1e-9);
      out.push([pts[k][0] + w * (pts[k + 1][0] - pts[k][0]), pts[k][1] + w * (pts[k + 1][1] - pts[k][1])]);
    }
    return out.map(([x, z]) => [Number(x.toFixed(3)), Number(z.toFixed(3))]);
  }

  // The request's control: the path (the body starts facing along it) and the pinned poses.
  function control() {
    const path = waypoints();
    const out = {};
    if (path.length >= 2) {
      const [a, b] = [path[0], path[1]];
      const heading = (Math.atan2(b[0] - a[0], b[1] - a[1]) * 180) / Math.PI;
      out.path = path.map(([x, z], i) => (i === 0 ? { x, z, heading: Number(heading.toFixed(1)) } : [x, z]));
    }
    if (cs.pins.length) out.keyframes = cs.pins.map((p) => ({ frame: p.frame, pose: p.pose }));
    return Object.keys(out).length ? out : null;
  }

  function redraw() {
    const canvas = $("floor");
    if (!canvas) return;
    const g = canvas.getContext("2d");
    g.clearRect(0, 0, canvas.width, canvas.height);
    g.strokeStyle = "#e3e6ec";
    g.lineWidth = 1;
    for (let m = -HALF_SPAN; m <= HALF_SPAN; m += 0.5) {
      const [px] = toCanvas(canvas, [m, 0]);
      const [, pz] = toCanvas(canvas, [0, m]);
      g.beginPath(); g.moveTo(px, 0); g.lineTo(px, canvas.height); g.stroke();
      g.beginPath(); g.moveTo(0, pz); g.lineTo(canvas.width, pz); g.stroke();
    }
    const line = (points, colour, width) => {
      if (points.length < 2) return;
      g.strokeStyle = colour;
      g.lineWidth = width;
      g.beginPath();
      points.forEach((p, i) => { const [cx, cy] = toCanvas(canvas, p); if (i) g.lineTo(cx, cy); else g.moveTo(cx, cy); });
      g.stroke();
    };
    const motion = window.mlct && window.mlct.state.motion;
    if (motion) line(motion.joints.map((pose) => [pose[0][0], pose[0][2]]), "#a5b4fc", 3);
    line(cs.drawn, "#4f46e5", 2);
    for (const p of waypoints()) {
      const [cx, cy] = toCanvas(canvas, p);
      g.fillStyle = "#4f46e5";
      g.fillRect(cx - 2, cy - 2, 4, 4);
    }
    if (motion && window.mlct.state.frame >= 0) {
      const root = motion.joints[window.mlct.state.frame][0];
      const [cx, cy] = toCanvas(canvas, [root[0], root[2]]);
      g.fillStyle = "#111827";
      g.beginPath(); g.arc(cx, cy, 4, 0, 2 * Math.PI); g.fill();
    }
    $("pins").textContent = cs.pins.length
      ? `pinned: ${cs.pins.map((p) => `frame ${p.frame}`).join(", ")}` : "";
  }

  function bind() {
    const canvas = $("floor");
    canvas.addEventListener("pointerdown", (event) => {
      cs.drawing = true;
      cs.drawn = [toFloor(canvas, event)];
      canvas.setPointerCapture(event.pointerId);
    });
    canvas.addEventListener("pointermove", (event) => {
      if (cs.drawing) cs.drawn.push(toFloor(canvas, event));
    });
    canvas.addEventListener("pointerup", () => {
      cs.drawing = false;
      // Long enough to walk the path at the bundled model's pace (its walks cover about
      // 2.3 m in 6 s; a path asking for more is met by sliding: docs/control.md)
      const path = waypoints();
      let length = 0;
      for (let i = 1; i < path.length; i++) length += Math.hypot(path[i][0] - path[i - 1][0], path[i][1] - path[i - 1][1]);
      const slider = $("seconds");
      const wanted = Math.min(Number(slider.max), Math.ceil((length / WALK_PACE) * 10) / 10);
      if (wanted > Number(slider.value)) {
        slider.value = String(wanted);
        slider.dispatchEvent(new Event("input"));
      }
    });
    $("clear-path").addEventListener("click", () => { cs.drawn = []; });
    $("pin-pose").addEventListener("click", () => {
      const state = window.mlct.state;
      if (!state.motion || state.frame < 0) return;
      const pose = state.motion.joints[state.frame];
      cs.pins = cs.pins.filter((p) => p.frame !== state.frame).concat([{ frame: state.frame, pose }]);
    });
    $("clear-pins").addEventListener("click", () => { cs.pins = []; });
    const loop = () => { redraw(); requestAnimationFrame(loop); };
    requestAnimationFrame(loop);
  }

  window.mlctControl = { control, waypoints, state: cs };
  window.addEventListener("DOMContentLoaded", bind);
})();
