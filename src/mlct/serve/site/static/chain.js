// Segments chained into one continuous motion: the page's port of generate/compose/long_motion.py's
// chain_segments. Each segment overlaps the next by `blend` frames; in the overlap the poses in
// the body's own frame are cross-faded, and so are the root's velocity and the heading's rate of
// turn, which are then integrated (blending world positions would drag the root between two
// diverging tracks). Joints are flat (frames * J * 3) arrays, as everywhere in the page.
"use strict";

// long_motion.heading: facing angle about +y, 0 when facing +Z, from the hips and shoulders.
export function headings(joints, frames, J, [rHip, lHip, rShoulder, lShoulder]) {
  const out = new Float64Array(frames);
  for (let t = 0; t < frames; t++) {
    const p = (j, k) => joints[(t * J + j) * 3 + k];
    const x = p(rHip, 0) - p(lHip, 0) + p(rShoulder, 0) - p(lShoulder, 0);
    const z = p(rHip, 2) - p(lHip, 2) + p(rShoulder, 2) - p(lShoulder, 2);
    out[t] = Math.atan2(z, -x); // forward = y x across: (across.z, -across.x)
  }
  return out;
}

// numpy.unwrap (discont pi)
export function unwrap(angles) {
  const out = Float64Array.from(angles);
  let correction = 0;
  for (let t = 1; t < angles.length; t++) {
    const d = angles[t] - angles[t - 1];
    let dmod = ((((d + Math.PI) % (2 * Math.PI)) + 2 * Math.PI) % (2 * Math.PI)) - Math.PI;
    if (dmod === -Math.PI && d > 0) dmod = Math.PI;
    if (Math.abs(d) >= Math.PI) correction += dmod - d;
    out[t] = angles[t] + correction;
  }
  return out;
}

// (x, z) turned by angle about +y (long_motion._turn_y)
const turn = (x, z, angle) => [Math.cos(angle) * x + Math.sin(angle) * z, -Math.sin(angle) * x + Math.cos(angle) * z];

// long_motion._decompose: root xz track, unwrapped heading, pose in the body's own frame.
export function decompose(joints, frames, J, face) {
  const root = [];
  for (let t = 0; t < frames; t++) root.push([joints[t * J * 3], joints[t * J * 3 + 2]]);
  const angle = Array.from(unwrap(headings(joints, frames, J, face)));
  const local = [];
  for (let t = 0; t < frames; t++) {
    const pose = new Float64Array(J * 3);
    for (let j = 0; j < J; j++) {
      const o = (t * J + j) * 3;
      const [x, z] = turn(joints[o] - root[t][0], joints[o + 2] - root[t][1], -angle[t]);
      pose[j * 3] = x;
      pose[j * 3 + 1] = joints[o + 1];
      pose[j * 3 + 2] = z;
    }
    local.push(pose);
  }
  return { root, angle, local };
}

// long_motion._continue: a track turned and moved to start at (root0, angle0).
function continueFrom(root0, angle0, root, angle) {
  const delta = angle0 - angle[0];
  return {
    root: root.map(([x, z]) => { const [a, b] = turn(x - root[0][0], z - root[0][1], delta); return [a + root0[0], b + root0[1]]; }),
    angle: angle.map((a) => a + delta),
  };
}

// long_motion._rates: per-frame change over the first n frames; frame 0 takes frame 1's.
function rates(track, n, sub) {
  const steps = [];
  for (let i = 0; i < n; i++) steps.push(sub(track[i + 1], track[i]));
  return [steps[0], ...steps.slice(0, n - 1)];
}

// chain_segments: segments [{joints, frames}], each overlapping the next by `blend` frames ->
// {joints (Float32Array; Float64Array with float64), frames, seams (the frame where each later
// segment's blend starts)}.
export function chainSegments(segments, blend, skeleton, float64 = false) {
  const J = skeleton.parents.length;
  const face = skeleton.face_joints;
  const sub2 = (a, b) => [a[0] - b[0], a[1] - b[1]];
  const sub1 = (a, b) => a - b;
  let { root, angle, local } = decompose(segments[0].joints, segments[0].frames, J, face);
  const seams = [];
  const weight = Array.from({ length: blend }, (_, i) => { const s = (i + 0.5) / blend; return s * s * (3 - 2 * s); });
  for (const segment of segments.slice(1)) {
    const start = root.length - blend;
    const next = decompose(segment.joints, segment.frames, J, face);
    const moved = continueFrom(root[start], angle[start], next.root, next.angle);
    const rootRate = rates(moved.root, blend, sub2);
    const angleRate = rates(moved.angle, blend, sub1);
    const mixedLocal = [];
    const mixedRoot = [];
    const mixedAngle = [];
    let [x, z] = root[start - 1];
    let a = angle[start - 1];
    for (let i = 0; i < blend; i++) {
      const w = weight[i];
      const pose = new Float64Array(J * 3);
      for (let k = 0; k < J * 3; k++) pose[k] = (1 - w) * local[start + i][k] + w * next.local[i][k];
      mixedLocal.push(pose);
      const [vx, vz] = sub2(root[start + i], root[start + i - 1]);
      x += (1 - w) * vx + w * rootRate[i][0];
      z += (1 - w) * vz + w * rootRate[i][1];
      a += (1 - w) * (angle[start + i] - angle[start + i - 1]) + w * angleRate[i];
      mixedRoot.push([x, z]);
      mixedAngle.push(a);
    }
    const rest = continueFrom(mixedRoot[blend - 1], mixedAngle[blend - 1], moved.root.slice(blend - 1), moved.angle.slice(blend - 1));
    root = [...root.slice(0, start), ...mixedRoot, ...rest.root.slice(1)];
    angle = [...angle.slice(0, start), ...mixedAngle, ...rest.angle.slice(1)];
    local = [...local.slice(0, start), ...mixedLocal, ...next.local.slice(blend)];
    seams.push(start);
  }
  const frames = root.length;
  const joints = float64 ? new Float64Array(frames * J * 3) : new Float32Array(frames * J * 3);
  for (let t = 0; t < frames; t++) {
    for (let j = 0; j < J; j++) {
      const o = j * 3;
      const [wx, wz] = turn(local[t][o], local[t][o + 2], angle[t]);
      joints[(t * J + j) * 3] = wx + root[t][0];
      joints[(t * J + j) * 3 + 1] = local[t][o + 1];
      joints[(t * J + j) * 3 + 2] = wz + root[t][1];
    }
  }
  return { joints, frames, seams };
}

// control_fit.reattach: the kept motion with the joints `parts` taken from `made` (an arm action
// made standing, put on a walking body): each such bone keeps the kept motion's length and
// points as made's does, turned from made's facing (hips) into kept's. Parents come before
// children in the skeleton's joint order.
export function reattach(made, kept, frames, parts, skeleton) {
  const J = skeleton.parents.length;
  const [rHip, lHip] = skeleton.face_joints;
  const out = Float64Array.from(kept);
  const hipHeading = (joints, t) => {
    const o = t * J * 3;
    return Math.atan2(joints[o + rHip * 3 + 2] - joints[o + lHip * 3 + 2], -(joints[o + rHip * 3] - joints[o + lHip * 3]));
  };
  const sorted = [...parts].sort((a, b) => a - b);
  for (let t = 0; t < frames; t++) {
    const delta = hipHeading(kept, t) - hipHeading(made, t);
    for (const j of sorted) {
      const p = skeleton.parents[j];
      const a = (t * J + j) * 3;
      const b = (t * J + p) * 3;
      const [bx, bz] = turn(made[a] - made[b], made[a + 2] - made[b + 2], delta);
      const by = made[a + 1] - made[b + 1];
      const length = Math.hypot(kept[a] - kept[b], kept[a + 1] - kept[b + 1], kept[a + 2] - kept[b + 2]);
      const norm = Math.max(Math.hypot(bx, by, bz), 1e-9);
      out[a] = out[b] + (length * bx) / norm;
      out[a + 1] = out[b + 1] + (length * by) / norm;
      out[a + 2] = out[b + 2] + (length * bz) / norm;
    }
  }
  return Float32Array.from(out);
}
