// Features -> joints and the motion's files, as mlct.motion.features.recover_from_ric and
// mlct.generate.output.exports write them (same formulas; float64 here, float32 results).
"use strict";

// qrot(q, v) for a yaw quaternion q = (c, 0, s, 0): v + 2 (w (u x v) + u x (u x v)), u = (0, s, 0).
function yaw(c, s, vx, vy, vz) {
  // u x v = (s vz, 0, -s vx); u x (u x v) = (-s^2 vx, 0, -s^2 vz)
  return [vx + 2 * (c * s * vz - s * s * vx), vy, vz + 2 * (-c * s * vx - s * s * vz)];
}

// features: Float32Array (T * D), denormalized -> Float32Array (T * J * 3), J = (D + 1) / 12.
export function recoverFromRic(features, frames, dim) {
  const joints = (dim + 1) / 12;
  const out = new Float32Array(frames * joints * 3);
  let half = 0; // the root's half yaw angle: running sum of the rotation velocities
  let x = 0;
  let z = 0; // the root's xz: running sum of the velocities turned to the world frame
  for (let t = 0; t < frames; t++) {
    const f = t * dim;
    if (t > 0) half += features[f - dim];
    const c = Math.cos(half);
    const s = -Math.sin(half); // qinv of (cos, 0, sin, 0)
    if (t > 0) {
      const v = yaw(c, s, features[f - dim + 1], 0, features[f - dim + 2]);
      x += v[0];
      z += v[2];
    }
    const o = t * joints * 3;
    out[o] = x;
    out[o + 1] = features[f + 3];
    out[o + 2] = z;
    for (let j = 1; j < joints; j++) {
      const r = f + 4 + (j - 1) * 3;
      const p = yaw(c, s, features[r], features[r + 1], features[r + 2]);
      out[o + 3 * j] = p[0] + x;
      out[o + 3 * j + 1] = p[1];
      out[o + 3 * j + 2] = p[2] + z;
    }
  }
  return out;
}

// The .json of mlct.generate.output.exports.motion_json: joints as nested [T][J][3] lists, 0.1 mm.
export function motionJson(motion) {
  const { skeleton, frames, joints } = motion;
  const J = skeleton.joint_names.length;
  const rows = [];
  for (let t = 0; t < frames; t++) {
    const pose = [];
    for (let j = 0; j < J; j++) {
      const o = (t * J + j) * 3;
      pose.push([0, 1, 2].map((k) => Math.round(joints[o + k] * 1e4) / 1e4));
    }
    rows.push(pose);
  }
  const record = { format: "mlct-motion", version: 1, text: motion.text, fps: skeleton.fps,
    skeleton: skeleton.name, unit: skeleton.unit, joint_names: skeleton.joint_names,
    parents: skeleton.parents, frames, seed: motion.seed, joints: rows };
  if (motion.footLock) record.foot_contacts = footContacts(joints, frames, skeleton, motion.footLock);
  return record;
}

// [left, right] per frame, 1 where that foot stands on the floor: foot_lock.foot_contacts
// (the toe, or the heel under ankle_height, low and slow for min_frames or more).
export function footContacts(joints, frames, skeleton, lock) {
  const J = skeleton.parents.length;
  const at = (t, j) => (t * J + j) * 3;
  const scale = skeleton.unit === "mm" ? 1000 : 1;
  const out = Array.from({ length: frames }, () => [0, 0]);
  const toes = { ...lock, max_hold: Infinity };
  const heels = { ...toes, height: lock.ankle_height };
  [skeleton.foot_left, skeleton.foot_right].forEach(([ankle, toe], side) => {
    for (const [joint, rule] of [[toe, toes], [ankle, heels]]) {
      for (const [start, end] of contactSpans(joints, frames, at, joint, skeleton.fps, scale, rule)) {
        for (let t = start; t < end; t++) out[t][side] = 1;
      }
    }
  });
  return out;
}

// A .npy (version 1.0, little-endian float32, C order) of joints (T, J, 3), as numpy.save.
export function npyBytes(data, shape) {
  let header = `{'descr': '<f4', 'fortran_order': False, 'shape': (${shape.join(", ")}${shape.length === 1 ? "," : ""}), }`;
  const unpadded = 10 + header.length + 1;
  header += " ".repeat((64 - (unpadded % 64)) % 64) + "\n";
  const head = new Uint8Array(10 + header.length);
  head.set([0x93, 0x4e, 0x55, 0x4d, 0x50, 0x59, 1, 0]); // \x93NUMPY v1.0
  new DataView(head.buffer).setUint16(8, header.length, true);
  for (let i = 0; i < header.length; i++) head[10 + i] = header.charCodeAt(i);
  const body = new Uint8Array(data.buffer, data.byteOffset, data.byteLength); // little-endian hosts
  const out = new Uint8Array(head.length + body.length);
  out.set(head);
  out.set(body, head.length);
  return out;
}

// Planted feet: mlct.motion.foot_lock.lock_feet, the same thresholds and formulas (float64
// here). A foot whose toe is low and slow for min_frames or more, straying at most max_hold
// from its mean, is held at that mean; the hold fades in and out over `blend` frames; the
// leg follows by two-bone IK from the hip. joints: Float32Array (frames * J * 3).
export function lockFeet(joints, frames, skeleton, lock) {
  const J = skeleton.parents.length;
  const out = Float64Array.from(joints);
  const scale = skeleton.unit === "mm" ? 1000 : 1;
  const at = (t, j) => (t * J + j) * 3;
  for (const [ankle, toe] of [skeleton.foot_left, skeleton.foot_right]) {
    const knee = skeleton.parents[ankle];
    const hip = skeleton.parents[knee];
    const spans = contactSpans(out, frames, at, toe, skeleton.fps, scale, lock);
    if (!spans.length) continue;
    const offset = holdOffsets(out, frames, at, toe, spans, lock.blend);
    const foot = [];
    for (let j = 0; j < J; j++) {
      for (let p = skeleton.parents[j]; p >= 0; p = skeleton.parents[p]) {
        if (p === ankle) { foot.push(j); break; }
      }
    }
    for (let t = 0; t < frames; t++) {
      const ox = offset[2 * t];
      const oz = offset[2 * t + 1];
      if (Math.abs(ox) + Math.abs(oz) === 0) continue;
      const point = (j) => out.slice(at(t, j), at(t, j) + 3);
      const A = point(ankle);
      const [K, N] = twoBoneIk(point(hip), point(knee), A, [A[0] + ox, A[1], A[2] + oz]);
      for (const j of foot) for (let k = 0; k < 3; k++) out[at(t, j) + k] += N[k] - A[k];
      for (let k = 0; k < 3; k++) {
        out[at(t, knee) + k] = K[k];
        out[at(t, ankle) + k] = N[k];
      }
    }
  }
  return Float32Array.from(out);
}

function contactSpans(joints, frames, at, toe, fps, scale, lock) {
  if (frames < 2) return [];
  const x = (t) => joints[at(t, toe)];
  const z = (t) => joints[at(t, toe) + 2];
  const standing = [];
  for (let t = 0; t < frames; t++) {
    const [a, b, h] = t === 0 ? [1, 0, 1] : t === frames - 1 ? [t, t - 1, 1] : [t + 1, t - 1, 2];
    const speed = (Math.hypot((x(a) - x(b)) / h, (z(a) - z(b)) / h) * fps) / scale; // np.gradient
    standing.push(joints[at(t, toe) + 1] / scale < lock.height && speed < lock.speed);
  }
  standing.push(false);
  const spans = [];
  let start = null;
  standing.forEach((on, t) => {
    if (on && start === null) start = t;
    else if (!on && start !== null) {
      let mx = 0;
      let mz = 0;
      for (let s = start; s < t; s++) { mx += x(s); mz += z(s); }
      mx /= t - start;
      mz /= t - start;
      let stray = 0;
      for (let s = start; s < t; s++) stray = Math.max(stray, Math.hypot(x(s) - mx, z(s) - mz));
      if (t - start >= lock.min_frames && stray / scale <= lock.max_hold) spans.push([start, t]);
      start = null;
    }
  });
  return spans;
}

const smoothstep = (v) => v * v * (3 - 2 * v);
const clip01 = (v) => Math.min(1, Math.max(0, v));

function holdOffsets(joints, frames, at, toe, spans, blend) {
  const offset = new Float64Array(frames * 2);
  for (const [start, end] of spans) {
    let mx = 0;
    let mz = 0;
    for (let t = start; t < end; t++) { mx += joints[at(t, toe)]; mz += joints[at(t, toe) + 2]; }
    mx /= end - start;
    mz /= end - start;
    for (let t = start; t < end; t++) {
      offset[2 * t] = mx - joints[at(t, toe)];
      offset[2 * t + 1] = mz - joints[at(t, toe) + 2];
    }
  }
  const edges = [[null, null], ...spans, [null, null]];
  for (let e = 0; e + 1 < edges.length; e++) {
    const gapStart = edges[e][1] ?? 0;
    const gapEnd = edges[e + 1][0] ?? frames;
    if (gapEnd <= gapStart) continue;
    const before = gapStart > 0 ? [offset[2 * gapStart - 2], offset[2 * gapStart - 1]] : [0, 0];
    const after = gapEnd < frames ? [offset[2 * gapEnd], offset[2 * gapEnd + 1]] : [0, 0];
    const slide = gapEnd - gapStart <= 2 * blend && gapStart > 0 && gapEnd < frames;
    for (let t = gapStart; t < gapEnd; t++) {
      let wOut;
      let wIn;
      if (slide) { // a short lift between two contacts: one offset slides into the next
        wIn = smoothstep((t - gapStart + 1) / (gapEnd - gapStart + 1));
        wOut = 1 - wIn;
      } else {
        wOut = smoothstep(clip01(1 - (t - gapStart + 1) / (blend + 1)));
        wIn = smoothstep(clip01(1 - (gapEnd - t) / (blend + 1)));
      }
      offset[2 * t] = wOut * before[0] + wIn * after[0];
      offset[2 * t + 1] = wOut * before[1] + wIn * after[1];
    }
  }
  return offset;
}

const sub = (a, b) => a.map((v, i) => v - b[i]);
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.hypot(a[0], a[1], a[2]);
const scaled = (a, s) => a.map((v) => v * s);

// (knee, ankle): foot_lock.two_bone_ik for one frame.
function twoBoneIk(hip, knee, ankle, target) {
  const thigh = norm(sub(knee, hip));
  const shin = norm(sub(ankle, knee));
  const reach = sub(target, hip);
  let distance = norm(reach);
  const direction = scaled(reach, 1 / Math.max(distance, 1e-9));
  distance = Math.min(Math.max(distance, Math.abs(thigh - shin) * 1.001 + 1e-9), (thigh + shin) * 0.999);
  const oldAxis0 = sub(ankle, hip);
  const oldAxis = scaled(oldAxis0, 1 / Math.max(norm(oldAxis0), 1e-9));
  const toKnee = sub(knee, hip);
  const pole = sub(toKnee, scaled(oldAxis, dot(toKnee, oldAxis)));
  let bend = sub(pole, scaled(direction, dot(pole, direction)));
  if (!(norm(bend) > 1e-6)) bend = sub(oldAxis, scaled(direction, dot(oldAxis, direction)));
  bend = scaled(bend, 1 / Math.max(norm(bend), 1e-9));
  const cosHip = Math.min(1, Math.max(-1, (thigh * thigh + distance * distance - shin * shin) / (2 * thigh * distance)));
  const sinHip = Math.sqrt(1 - cosHip * cosHip);
  const newKnee = hip.map((h, k) => h + thigh * (cosHip * direction[k] + sinHip * bend[k]));
  const newAnkle = hip.map((h, k) => h + distance * direction[k]);
  return [newKnee, newAnkle];
}
