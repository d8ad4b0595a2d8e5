// The page's GLB download: the BVH's rotation fit (bvh.js) as a glTF 2.0 animation on a node
// hierarchy, one node per joint (its rest translation the bone's offset in the rest pose, in
// metres; no rest rotation), every joint's rotation and the root's translation keyed at every
// frame: the layout of mlct.motion.gltf's writer, without its capsule mesh. Written by three's
// GLTFExporter (the pinned three package); Blender, three.js and game engines import it.
"use strict";

import * as THREE from "three";
import { GLTFExporter } from "./vendor/GLTFExporter.js";
import { fitBvh } from "./bvh.js";

const CM = 0.01; // bvh.js fits in centimetres; glTF is in metres

export async function glbBytes(motion) {
  const { skeleton, frames, joints } = motion;
  const fit = fitBvh(joints, frames, skeleton);
  const names = skeleton.joint_names;
  const bones = names.map((name, j) => {
    const bone = new THREE.Bone();
    bone.name = name;
    bone.position.set(...fit.offsets[j].map((v) => v * CM));
    return bone;
  });
  skeleton.parents.forEach((p, j) => { if (p >= 0) bones[p].add(bones[j]); });
  const root = bones[fit.order[0]];
  const times = Float32Array.from({ length: frames }, (_, t) => t / skeleton.fps);
  const m = new THREE.Matrix4();
  const q = new THREE.Quaternion();
  const tracks = names.map((name, j) => {
    const values = new Float32Array(frames * 4);
    for (let t = 0; t < frames; t++) {
      const r = fit.locals[t][j];
      m.set(r[0], r[1], r[2], 0, r[3], r[4], r[5], 0, r[6], r[7], r[8], 0, 0, 0, 0, 1);
      q.setFromRotationMatrix(m);
      if (t > 0 && q.x * values[4 * t - 4] + q.y * values[4 * t - 3] + q.z * values[4 * t - 2] + q.w * values[4 * t - 1] < 0) {
        q.set(-q.x, -q.y, -q.z, -q.w); // the same turn, the short way from the previous key
      }
      values.set([q.x, q.y, q.z, q.w], 4 * t);
    }
    return new THREE.QuaternionKeyframeTrack(`${name}.quaternion`, times, values);
  });
  const position = Float32Array.from({ length: frames * 3 }, (_, i) => fit.root[Math.floor(i / 3)][i % 3] * CM);
  tracks.push(new THREE.VectorKeyframeTrack(`${root.name}.position`, times, position));
  const clip = new THREE.AnimationClip("motion", frames > 1 ? times[frames - 1] : 0, tracks);
  const exporter = new GLTFExporter();
  return new Uint8Array(await exporter.parseAsync(root, { binary: true, animations: [clip] }));
}
