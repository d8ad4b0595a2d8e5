// The page's BVH download: the motion's joint positions fitted to a rigid skeleton with one
// rotation per joint a frame, written as mlct.motion.bvh writes its files (hierarchy in the
// skeleton's depth-first order, End Sites at half the leaf's bone, root with 6 channels
// Xposition Yposition Zposition Zrotation Xrotation Yrotation, others Z X Y, degrees unwrapped
// over time, centimetres, 4 decimals).
//
// The fit is a shorter form of mlct.motion.rigfit.fit_rig, the one Python's writers share:
// - bone lengths: the motion's median; rest offsets along the skeleton's rest pose
//   (Skeleton.rest_directions, in model.json); a joint with several children (pelvis, upper
//   spine) turns them as one rigid group whose shape is the clip's mean (generalized
//   Procrustes, 3 rounds), turned onto the rest pose;
// - the root follows the input's root exactly; a multi-child joint turns by the least-squares
//   rotation of its group (Kabsch, solved as Horn's quaternion eigenvector);
// - every other joint: the shortest turn aiming its bone from the joint as already rebuilt at
//   the input's child (so errors do not add up along a chain); leaves keep their parent's turn.
// Left out (docs/web.md): rigfit's two-bone IK of the limbs and its heel/toe choice (there a
// foot's end is off by its bone's stretch, a few mm, instead of exact) and its twist smoothing
// (positions cannot show a bone's spin about itself; a mesh bound to the file can). The joints
// of the file are the input's to about the bones' stretch (tests/test_web_static_e2e.py reads
// the page's file back with mlct.motion.bvh.read_bvh).
"use strict";

import { median } from "./pymath.js";

const TO_CM = { m: 100, mm: 0.1 };
const END_SITE_FRACTION = 0.5;
const PROCRUSTES_ROUNDS = 3;

// --- small 3-vector and 3x3 (row-major arrays of 9) helpers ---
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const norm = (a) => Math.sqrt(dot(a, a));
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const apply = (m, v) => [m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
  m[6] * v[0] + m[7] * v[1] + m[8] * v[2]];
const applyT = (m, v) => [m[0] * v[0] + m[3] * v[1] + m[6] * v[2], m[1] * v[0] + m[4] * v[1] + m[7] * v[2],
  m[2] * v[0] + m[5] * v[1] + m[8] * v[2]];
function mul(a, b) {
  const out = new Array(9);
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) {
    out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
  }
  return out;
}
const transpose = (m) => [m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8]];
const IDENTITY = [1, 0, 0, 0, 1, 0, 0, 0, 1];

function quatToMatrix([w, x, y, z]) {
  return [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
    2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
    2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)];
}

// The shortest rotation turning direction a onto direction b.
function between(a, b) {
  const u = scale(a, 1 / Math.max(norm(a), 1e-12));
  const v = scale(b, 1 / Math.max(norm(b), 1e-12));
  const c = dot(u, v);
  if (c < -1 + 1e-12) { // opposite: half a turn about any axis perpendicular to u
    const axis = Math.abs(u[0]) < 0.9 ? cross(u, [1, 0, 0]) : cross(u, [0, 1, 0]);
    const n = scale(axis, 1 / norm(axis));
    return quatToMatrix([0, n[0], n[1], n[2]]);
  }
  const w = cross(u, v);
  const q = [1 + c, w[0], w[1], w[2]];
  const len = Math.hypot(...q);
  return quatToMatrix(q.map((x) => x / len));
}

// The eigenvector of the largest eigenvalue of a symmetric 4x4 matrix (cyclic Jacobi).
function topEigenvector(m) {
  const a = m.map((row) => row.slice());
  const v = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
  for (let sweep = 0; sweep < 50; sweep++) {
    let off = 0;
    for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) off += a[p][q] * a[p][q];
    if (off < 1e-30) break;
    for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) {
      if (Math.abs(a[p][q]) < 1e-300) continue;
      const theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
      const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
      const c = 1 / Math.sqrt(t * t + 1);
      const s = t * c;
      for (let k = 0; k < 4; k++) { // A <- A J (columns p, q)
        const akp = a[k][p];
        const akq = a[k][q];
        a[k][p] = c * akp - s * akq;
        a[k][q] = s * akp + c * akq;
      }
      for (let k = 0; k < 4; k++) { // A <- J^T A (rows p, q)
        const apk = a[p][k];
        const aqk = a[q][k];
        a[p][k] = c * apk - s * aqk;
        a[q][k] = s * apk + c * aqk;
      }
      for (let k = 0; k < 4; k++) {
        const vkp = v[k][p];
        const vkq = v[k][q];
        v[k][p] = c * vkp - s * vkq;
        v[k][q] = s * vkp + c * vkq;
      }
    }
  }
  let best = 0;
  for (let i = 1; i < 4; i++) if (a[i][i] > a[best][best]) best = i;
  return [v[0][best], v[1][best], v[2][best], v[3][best]];
}

// Kabsch: the rotation R minimizing sum |R s_i - t_i|^2 (Horn's quaternion method).
export function kabsch(sources, targets) {
  let sxx = 0, sxy = 0, sxz = 0, syx = 0, syy = 0, syz = 0, szx = 0, szy = 0, szz = 0;
  for (let i = 0; i < sources.length; i++) {
    const [ax, ay, az] = sources[i];
    const [bx, by, bz] = targets[i];
    sxx += ax * bx; sxy += ax * by; sxz += ax * bz;
    syx += ay * bx; syy += ay * by; syz += ay * bz;
    szx += az * bx; szy += az * by; szz += az * bz;
  }
  const n = [[sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
    [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
    [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
    [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz]];
  return quatToMatrix(topEigenvector(n));
}

// Euler angles (degrees) of R = Rz(a) Rx(b) Ry(c): intrinsic Z-X-Y, as the channels list them.
function eulerZXY(m) {
  const b = Math.asin(Math.max(-1, Math.min(1, m[7])));
  let a, c;
  if (Math.abs(m[7]) < 1 - 1e-9) {
    a = Math.atan2(-m[1], m[4]);
    c = Math.atan2(-m[6], m[8]);
  } else { // gimbal lock: the Z and Y turns share an axis; all of it goes to Z
    a = Math.atan2(m[3], m[0]);
    c = 0;
  }
  const deg = 180 / Math.PI;
  return [a * deg, b * deg, c * deg];
}

function childrenOf(parents) {
  const children = parents.map(() => []);
  parents.forEach((p, j) => { if (p >= 0) children[p].push(j); });
  return children;
}

function depthFirst(children) {
  const order = [];
  const stack = [0];
  while (stack.length) {
    const j = stack.pop();
    order.push(j);
    for (let k = children[j].length - 1; k >= 0; k--) stack.push(children[j][k]);
  }
  return order;
}

// joints (T * J * 3, skeleton units) -> {order, offsets (J x 3), root (T x 3), euler (T x J x 3),
// positions (T x J x 3): the fitted skeleton's joints, locals (T x J 3x3 rotations), children},
// lengths in centimetres.
export function fitBvh(joints, frames, skeleton) {
  const { parents, rest_directions: rest } = skeleton;
  if (!rest) throw new Error("this site's model.json has no rest pose; export it again for BVH");
  const J = parents.length;
  const unit = TO_CM[skeleton.unit];
  const x = (t, j) => { const o = (t * J + j) * 3; return [joints[o] * unit, joints[o + 1] * unit, joints[o + 2] * unit]; };
  const children = childrenOf(parents);
  const order = depthFirst(children);
  const lengths = parents.map((p, j) => (p < 0 ? 0 : median(Array.from({ length: frames }, (_, t) => norm(sub(x(t, j), x(t, p)))))));
  const offsets = rest.map((d, j) => scale(d, lengths[j]));
  for (let j = 0; j < J; j++) {
    const kids = children[j];
    if (kids.length < 2) continue;
    const bones = Array.from({ length: frames }, (_, t) => kids.map((k) => sub(x(t, k), x(t, j))));
    let shape = kids.map((k) => offsets[k]);
    for (let round = 0; round < PROCRUSTES_ROUNDS; round++) { // the mean of R_t^T b over frames
      const sum = kids.map(() => [0, 0, 0]);
      for (const b of bones) {
        const r = kabsch(shape, b);
        b.forEach((v, i) => { sum[i] = add(sum[i], applyT(r, v)); });
      }
      shape = sum.map((v) => scale(v, 1 / frames));
    }
    const turn = kabsch(shape, kids.map((k) => offsets[k])); // onto the rest pose
    kids.forEach((k, i) => { const v = apply(turn, shape[i]); offsets[k] = scale(v, lengths[k] / Math.max(norm(v), 1e-12)); });
  }
  offsets[0] = [0, 0, 0];

  const root = [];
  const euler = [];
  const positions = [];
  const locals = []; // (T x J) 3x3 local rotations (row-major), for the GLB writer (glb.js)
  for (let t = 0; t < frames; t++) {
    const world = new Array(J);
    const local = new Array(J);
    const fitted = new Array(J);
    fitted[order[0]] = x(t, order[0]);
    for (const j of order) {
      const p = parents[j];
      const parentRot = p < 0 ? IDENTITY : world[p];
      const kids = children[j];
      if (kids.length === 0) world[j] = parentRot;
      else if (kids.length === 1) {
        const current = apply(parentRot, offsets[kids[0]]);
        world[j] = mul(between(current, sub(x(t, kids[0]), fitted[j])), parentRot);
      } else {
        world[j] = kabsch(kids.map((k) => offsets[k]), kids.map((k) => sub(x(t, k), fitted[j])));
      }
      local[j] = p < 0 ? world[j] : mul(transpose(parentRot), world[j]);
      for (const k of kids) fitted[k] = add(fitted[j], apply(world[j], offsets[k]));
    }
    root.push(fitted[order[0]]);
    locals.push(local);
    euler.push(local.map(eulerZXY));
    positions.push(fitted);
  }
  for (let j = 0; j < J; j++) for (let k = 0; k < 3; k++) { // unwrapped: no jump of 360
    for (let t = 1; t < frames; t++) {
      const step = euler[t][j][k] - euler[t - 1][j][k];
      euler[t][j][k] -= 360 * Math.round(step / 360);
    }
  }
  return { order, offsets, root, euler, positions, children, locals };
}

const fixed = (v, places = 4) => (Math.round(v * 10 ** places) / 10 ** places + 0).toFixed(places);
const vector = (v) => v.map((c) => fixed(c)).join(" ");

// The BVH text of a page motion ({joints, frames, skeleton}).
export function bvhText(motion) {
  const { skeleton, frames, joints } = motion;
  const names = skeleton.joint_names;
  const fit = fitBvh(joints, frames, skeleton);
  const lines = ["HIERARCHY"];
  const block = (j, depth) => {
    const pad = "  ".repeat(depth);
    lines.push(`${pad}${depth === 0 ? "ROOT" : "JOINT"} ${names[j]}`, `${pad}{`,
      `${pad}  OFFSET ${vector(fit.offsets[j])}`,
      `${pad}  CHANNELS ${depth === 0 ? "6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" : "3 Zrotation Xrotation Yrotation"}`);
    for (const k of fit.children[j]) block(k, depth + 1);
    if (fit.children[j].length === 0) {
      lines.push(`${pad}  End Site`, `${pad}  {`, `${pad}    OFFSET ${vector(scale(fit.offsets[j], END_SITE_FRACTION))}`, `${pad}  }`);
    }
    lines.push(`${pad}}`);
  };
  block(fit.order[0], 0);
  lines.push("MOTION", `Frames: ${frames}`, `Frame Time: ${Number((1 / skeleton.fps).toPrecision(9))}`);
  for (let t = 0; t < frames; t++) {
    lines.push([...fit.root[t], ...fit.order.flatMap((j) => fit.euler[t][j])].map((v) => fixed(v)).join(" "));
  }
  return lines.join("\n") + "\n";
}
