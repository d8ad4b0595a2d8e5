// A gait asked for longer than its natural length that stopped early, made again as takes of its
// natural length chained into one continuing motion: the page's port of generate/compose/keep_going.py
// (its docstring says why and how). The patterns and constants are Python's, read from
// model.json ("keep_going": keep_going.portable_rules). Joints are flat (frames * J * 3) arrays.
"use strict";

import { chainSegments, decompose, headings, unwrap } from "./chain.js";
import { median, percentile, roundHalfEven as pyRound } from "./pymath.js";

const mean = (values) => values.reduce((a, b) => a + b, 0) / values.length;

export class KeepGoing {
  constructor(rules, skeleton) {
    this.rules = rules;
    this.skeleton = skeleton;
    this.counted = new RegExp(rules.counted, "i");
    this.turning = new RegExp(rules.turning, "i");
    this.J = skeleton.parents.length;
    this.fps = skeleton.fps;
  }

  // names_an_end: a count, a distance or a turn says when the action ends
  namesAnEnd(text) { return this.counted.test(text) || this.turning.test(text); }

  root(joints, frames) {
    return Array.from({ length: frames }, (_, t) => [joints[t * this.J * 3], joints[t * this.J * 3 + 2]]);
  }

  // ground_speed: the pelvis's horizontal speed, m/s, averaged over ~half a second
  groundSpeed(joints, frames) {
    const root = this.root(joints, frames);
    const step = [];
    for (let t = 1; t < frames; t++) step.push(Math.hypot(root[t][0] - root[t - 1][0], root[t][1] - root[t - 1][1]) * this.fps);
    const speed = step.length ? [step[0], ...step] : new Array(frames).fill(0);
    const width = Math.max(1, pyRound(this.rules.smooth_seconds * this.fps));
    const left = Math.floor(width / 2);
    const padded = [...new Array(left).fill(speed[0]), ...speed, ...new Array(width - 1 - left).fill(speed[speed.length - 1])];
    return speed.map((_, t) => { let sum = 0; for (let i = 0; i < width; i++) sum += padded[t + i] / width; return sum; });
  }

  // straightness: the median over 1-s windows of net ground displacement over path length
  straightness(joints, from, to) {
    const root = this.root(joints, to).slice(from);
    const width = pyRound(this.fps);
    const ratios = [];
    for (let start = 0; start < root.length - width; start += Math.max(1, Math.floor(width / 2))) {
      let path = 0;
      for (let t = start + 1; t <= start + width; t++) path += Math.hypot(root[t][0] - root[t - 1][0], root[t][1] - root[t - 1][1]);
      if (path > 1e-6) ratios.push(Math.hypot(root[start + width][0] - root[start][0], root[start + width][1] - root[start][1]) / path);
    }
    return ratios.length ? median(ratios) : 0;
  }

  // turn_rate: degrees a second of the facing's net change over the stretch
  turnRate(joints, from, to) {
    const angle = unwrap(headings(joints, to, this.J, this.skeleton.face_joints).slice(from));
    return (Math.abs(angle[angle.length - 1] - angle[0]) * 180 / Math.PI) * this.fps / Math.max(angle.length - 1, 1);
  }

  // _gait_pace: the median ground speed over the natural stretch of a gait, else null; a motion
  // that stops before that stretch ends is judged again over its moving stretch when its feet
  // alternate through it (min_steps)
  gaitPace(joints, frames, speed, natural) {
    const lead = pyRound(0.5 * this.fps);
    const end = Math.min(pyRound((natural - 0.5) * this.fps), frames);
    let pace = this.paceOver(joints, speed, lead, end);
    if (pace === null) {
      const stop = this.movingStretch(joints, frames)[1];
      if (lead < stop && stop < end && this.footSwaps(joints, lead, stop) >= this.rules.min_steps) {
        pace = this.paceOver(joints, speed, lead, stop);
      }
    }
    return pace;
  }

  // foot_swaps: how often the lower foot changes side, over frames [from, to)
  footSwaps(joints, from, to, hysteresis = 0.03) {
    const low = (feet, t) => Math.min(...feet.map((j) => joints[(t * this.J + j) * 3 + 1]));
    let swaps = 0, lower = 0;
    for (let t = from; t < to; t++) {
      const d = low(this.skeleton.foot_left, t) - low(this.skeleton.foot_right, t);
      const now = d < -hysteresis ? -1 : d > hysteresis ? 1 : lower;
      if (lower !== 0 && now !== lower) swaps += 1;
      lower = now;
    }
    return swaps;
  }

  // _pace_over: gaitPace's test over frames [lead, end)
  paceOver(joints, speed, lead, end) {
    const r = this.rules;
    const stretch = speed.slice(lead, Math.max(lead, end));
    if (stretch.length < this.fps) return null;
    const later = stretch.slice(Math.floor(stretch.length / 2));
    const gait = percentile(stretch, 25) >= r.moving_speed
      && percentile(later, 25) >= r.steady_share * percentile(later, 75)
      && this.straightness(joints, lead, end) >= r.min_straightness
      && this.turnRate(joints, lead, end) <= r.max_turn_rate;
    return gait ? median(stretch) : null;
  }

  // is_gait: the motion goes somewhere through its natural length at a steady pace
  isGait(joints, frames, natural) { return this.gaitPace(joints, frames, this.groundSpeed(joints, frames), natural) !== null; }

  // stops_early: a gait standing still in its last second, asked for more than the margin longer
  stopsEarly(joints, frames, natural) {
    if (frames / this.fps < natural + this.rules.margin_seconds) return false;
    const speed = this.groundSpeed(joints, frames);
    const pace = this.gaitPace(joints, frames, speed, natural);
    return pace !== null && mean(speed.slice(-pyRound(this.fps))) < this.rules.stopped_share * pace;
  }

  segmentCount(frames, natural, blend) {
    const gain = Math.max(natural - Math.floor(natural / 2) - blend, 1);
    return Math.max(2, Math.ceil((frames - natural) / gain) + 2);
  }

  floorHeight(joints, frames) {
    const feet = [...this.skeleton.foot_left, ...this.skeleton.foot_right];
    return median(Array.from({ length: frames }, (_, t) => Math.min(...feet.map((j) => joints[(t * this.J + j) * 3 + 1]))));
  }

  movingStretch(joints, frames) {
    const speed = this.groundSpeed(joints, frames);
    const moving = speed.filter((v) => v >= this.rules.moving_speed);
    if (!moving.length) return [0, frames];
    const threshold = this.rules.moving_share * median(moving);
    const fast = speed.map((v, t) => (v >= threshold ? t : -1)).filter((t) => t >= 0);
    return [fast[0], fast[fast.length - 1] + 1];
  }

  legs() { // the pelvis, the feet, and the joints between them: the gait's phase
    const { parents, foot_left: left, foot_right: right } = this.skeleton;
    const between = new Set();
    for (const ankle of [left[0], right[0]]) for (let j = parents[ankle]; j > 0; j = parents[j]) between.add(j);
    return [0, ...left, ...right, ...[...between].sort((a, b) => a - b)];
  }

  // keep_going: segments [{joints, frames}] (takes of one prompt at its natural length) chained
  // as one continuing motion of `frames` -> {joints (Float32Array), seams}, or null when they do
  // not reach it.
  chain(segments, frames, blend) {
    const { J, fps } = this;
    const search = pyRound(1.2 * fps);
    if (segments.length < 2) return null;
    const floor = this.floorHeight(segments[0].joints, segments[0].frames);
    segments = segments.map(({ joints, frames: n }) => {
      const lift = floor - this.floorHeight(joints, n);
      const out = Float64Array.from(joints);
      for (let i = 1; i < out.length; i += 3) out[i] += lift;
      return { joints: out, frames: n };
    });
    const legs = this.legs();
    const local = segments.map(({ joints, frames: n }) => decompose(joints, n, J, this.skeleton.face_joints).local
      .map((pose) => legs.map((j) => [pose[j * 3], pose[j * 3 + 1], pose[j * 3 + 2]])));
    const distance = (a, b) => { // _pose_distances
      let sum = 0;
      let count = 0;
      a.forEach((pose, t) => pose.forEach((p, j) => { sum += Math.hypot(p[0] - b[t][j][0], p[1] - b[t][j][1], p[2] - b[t][j][2]); count++; }));
      return sum / count;
    };
    const stretches = segments.map(({ joints, frames: n }) => this.movingStretch(joints, n));
    const positions = (pieces) => { const out = []; let at = 0; for (const p of pieces) { out.push(at); at += p.end - p.start - blend; } return out; };
    const cut = (pieces, c) => {
      const at = positions(pieces);
      for (let index = 0; index < pieces.length; index++) {
        const p = pieces[index];
        if (at[index] + p.end - p.start >= c) {
          const kept = c - at[index];
          if (kept < 2 * blend && index > 0) return null;
          return [...pieces.slice(0, index), { segment: p.segment, start: p.start, end: p.start + kept }];
        }
      }
      return null;
    };
    const last = segments.length - 1;
    const pieces = [{ segment: 0, start: 0, end: stretches[0][1] }];
    const leadLast = segments[last].frames - stretches[last][0];
    for (let k = 1; k < last; k++) {
      const tip = pieces[pieces.length - 1];
      const at = positions(pieces)[pieces.length - 1] + tip.end - tip.start;
      if (at - blend + leadLast >= frames + search) break;
      const [first, end] = stretches[k];
      if (end - first < 2 * blend + 2) continue; // a take that hardly moved
      const tail = local[tip.segment].slice(tip.end - blend, tip.end);
      let best = [Infinity, first];
      for (let s = first; s < Math.max(first + 1, Math.min(first + search, end - 2 * blend)); s++) {
        if (s + blend > local[k].length) continue;
        const d = distance(tail, local[k].slice(s, s + blend));
        if (d < best[0] || (d === best[0] && s < best[1])) best = [d, s];
      }
      pieces.push({ segment: k, start: best[1], end });
    }
    const at = positions(pieces);
    const tip = pieces[pieces.length - 1];
    const length = at[at.length - 1] + tip.end - tip.start;
    const chain = pieces.flatMap((p, i) => local[p.segment].slice(p.start, p.end - (i < pieces.length - 1 ? blend : 0)));
    let best = null;
    const firstLast = stretches[last][0];
    const slack = Math.max(1, Math.min(Math.trunc(this.rules.max_warp * frames), search));
    for (let s = firstLast; s < Math.min(firstLast + search, segments[last].frames - blend - 1); s++) {
      const exact = frames + blend - (segments[last].frames - s); // the cut that needs no retiming
      for (let c = Math.max(blend + 1, exact - slack); c <= Math.min(length, exact + slack); c++) {
        const kept = cut(pieces, c);
        if (kept === null) continue;
        const score = distance(chain.slice(c - blend, c), local[last].slice(s, s + blend))
          + (this.rules.warp_cost * Math.abs(c - exact)) / frames;
        if (best === null || score < best.score) best = { score, kept, s };
      }
    }
    if (best === null) return null;
    const slice = (segment, from, to) => ({ joints: segment.joints.subarray(from * J * 3, to * J * 3), frames: to - from });
    const parts = [...best.kept.map((p) => slice(segments[p.segment], p.start, p.end)),
      slice(segments[last], best.s, segments[last].frames)];
    const chained = chainSegments(parts, blend, this.skeleton, true);
    const scale = (frames - 1) / Math.max(chained.frames - 1, 1);
    return { joints: retime(chained.joints, chained.frames, frames, J), seams: chained.seams.map((seam) => pyRound(seam * scale)) };
  }
}

// keep_going.retime: the same motion at a uniformly changed tempo (numpy's linspace, linear
// interpolation between frames), as float32
export function retime(joints, from, frames, J) {
  const out = new Float32Array(frames * J * 3);
  const step = frames > 1 ? (from - 1) / (frames - 1) : 0;
  for (let t = 0; t < frames; t++) {
    const at = t === frames - 1 ? from - 1 : t * step;
    const low = Math.floor(at);
    const high = Math.min(low + 1, from - 1);
    const w = at - low;
    for (let k = 0; k < J * 3; k++) out[t * J * 3 + k] = (1 - w) * joints[low * J * 3 + k] + w * joints[high * J * 3 + k];
  }
  return out;
}
