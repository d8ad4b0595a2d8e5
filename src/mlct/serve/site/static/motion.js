// Features -> joints and the motion's files, as mlct.motion.features.recover_from_ric and
// mlct.generate.exports write them (same formulas; float64 here, float32 results).
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

// The .json of mlct.generate.exports.motion_json: joints as nested [T][J][3] lists, 0.1 mm.
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
  return { format: "mlct-motion", version: 1, text: motion.text, fps: skeleton.fps,
    skeleton: skeleton.name, unit: skeleton.unit, joint_names: skeleton.joint_names,
    parents: skeleton.parents, frames, seed: motion.seed, joints: rows };
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
