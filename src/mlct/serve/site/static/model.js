// The model in the browser: text -> MiniLM (int8 ONNX) -> consistency sampler around the
// denoiser graph (Algorithm 2) -> decoder graph -> denormalize -> joints. The same steps as
// mlct's onnx backend (generate/backends/onnx/networks.py, generate/samplers/consistency.py), with the
// portable noise (noise.js) so that Python can give the same joints for a seed.
"use strict";

import * as ort from "./vendor/ort.wasm.min.mjs";
import { WordPieceTokenizer } from "./tokenizer.js";
import { PortableNoise } from "./noise.js";
import { lockFeet, recoverFromRic } from "./motion.js";
import { ActionSplitter, Durations, StatedSeconds, splitFrames } from "./compose.js";
import { chainSegments, reattach } from "./chain.js";
import { KeepGoing } from "./keepgoing.js";
import { roundHalfEven } from "./pymath.js";

const PY_SPACE = /[\s\x1c-\x1f\x85]/u; // what Python's str.split() splits on (U+FEFF is no space)
const CONTROL = /[\p{Cc}\p{Cf}\p{Cs}]/u;

// mlct.generate.compose.prompts.clean_prompt: white space runs collapsed; controls, empty, too long refused.
// text/sides.py's mirror: every side word swapped, capitals kept. Python's \b is Unicode-aware,
// hence the lookarounds on letters, marks, digits and "_" instead of JS's ASCII \b.
const SIDE_MIRROR = { left: "right", right: "left", clockwise: "counterclockwise",
  counterclockwise: "clockwise", anticlockwise: "clockwise" };
// As there, "right" naming no side ("a right angle", "all right", "right away", "right now") is
// left alone; SP is Python's \s (str.isspace: U+001C-U+001F and U+0085 too, U+FEFF not).
const SP = String.raw`(?:(?!\ufeff)[\s\x1c-\x1f\x85])`;
const NOT_WORD = String.raw`[\p{L}\p{M}\p{N}_]`;
const SIDE_WORD = new RegExp(
  String.raw`(?<!(?<!${NOT_WORD})all${SP})(?<!${NOT_WORD})(counterclockwise|anticlockwise|clockwise|right|left)(?!${NOT_WORD})`
  + String.raw`(?!(?:-|${SP})+angle)(?!${SP}+(?:away|now)(?!${NOT_WORD}))`, "giu");

export function mirrorSides(text) {
  return text.replace(SIDE_WORD, (word) => {
    const mirrored = SIDE_MIRROR[word.toLowerCase()];
    if (word === word.toUpperCase()) return mirrored.toUpperCase();
    return word[0] === word[0].toUpperCase() ? mirrored[0].toUpperCase() + mirrored.slice(1) : mirrored;
  });
}

export function cleanPrompt(text, maxChars) {
  for (const ch of text) {
    if (CONTROL.test(ch) && !(PY_SPACE.test(ch) && ch !== "\ufeff")) {
      throw new Error(`the prompt contains the control character U+${ch.codePointAt(0).toString(16).toUpperCase().padStart(4, "0")}`);
    }
  }
  const words = [];
  let word = "";
  for (const ch of text) {
    if (PY_SPACE.test(ch) && ch !== "\ufeff") { if (word) words.push(word); word = ""; } else word += ch;
  }
  if (word) words.push(word);
  const cleaned = words.join(" ");
  if (!cleaned) throw new Error("the prompt is empty; describe a motion, e.g. 'a person walks forward'");
  if (cleaned.length > maxChars) throw new Error(`the prompt has ${cleaned.length} characters; the limit is ${maxChars}`);
  return cleaned;
}

// A file's bytes; gzip's (1f 8b: the graphs and the WASM binary as export-web stores them,
// serve/site/pack.py) unpacked with the browser's DecompressionStream. A server that already
// unpacked a .gz (Content-Encoding: gzip) hands over the plain bytes, used as they are.
export async function fetchBytes(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`cannot load ${url}: HTTP ${response.status}`);
  const bytes = new Uint8Array(await response.arrayBuffer());
  if (bytes[0] !== 0x1f || bytes[1] !== 0x8b) return bytes;
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

export class MotionModel {
  static async load(base = new URL(".", import.meta.url).href, { threads = 1 } = {}) {
    ort.env.wasm.wasmPaths = new URL("vendor/", base).href;
    ort.env.wasm.numThreads = threads;
    const config = await (await fetch(new URL("model/model.json", base))).json();
    const vocab = await (await fetch(new URL(`model/${config.text_encoder.vocab}`, base))).text();
    // the runtime's binary, fetched here so that a gzipped one can be unpacked (older sites: ORT fetches it)
    if (config.wasm) ort.env.wasm.wasmBinary = await fetchBytes(new URL(`vendor/${config.wasm}`, base));
    // disable_quant_qdq: int8 weights dequantized in a graph (the int8-weights text encoder) are
    // folded into float32 once, when the session is made, instead of dequantized on every run;
    // the same arithmetic, as mlct's native sessions (onnx_io.session) set it too
    const options = { executionProviders: ["wasm"], graphOptimizationLevel: "all",
      extra: { session: { disable_quant_qdq: "1" } } };
    const session = async (name) => ort.InferenceSession.create(
      await fetchBytes(new URL(`model/${config.graphs[name]}`, base)), options);
    const [text, denoiser, decoder] = await Promise.all(["text_encoder", "denoiser", "decoder"].map(session));
    const sessions = { text, denoiser, decoder };
    if (config.critic) { // best of N (a model without a critic samples once)
      sessions.critic = await ort.InferenceSession.create(await fetchBytes(new URL(`model/${config.critic.graph}`, base)), options);
    }
    return new MotionModel(config, new WordPieceTokenizer(vocab, config.text_encoder), sessions, threads);
  }

  constructor(config, tokenizer, sessions, threads) {
    this.config = config;
    this.tokenizer = tokenizer;
    this.sessions = sessions;
    this.threads = threads;
    this.grid = Float32Array.from(config.sampler.grid);
    this.memo = new Map(); // text -> embedding: a repeated prompt skips the encoder (as the pipeline)
    // a sequence of actions made one part each and chained (a site made before has neither)
    this.splitter = config.sequence ? new ActionSplitter(config.sequence.rules) : null;
    this.durations = config.durations ? new Durations(config.durations) : null;
    this.stated = config.stated ? new StatedSeconds(config.stated) : null;
    this.keepGoing = config.keep_going && this.durations ? new KeepGoing(config.keep_going, config.skeleton) : null;
    // frames a one-action gait may last: past the window when it keeps going (pipeline.longest_gait)
    this.longestGait = this.keepGoing ? this.framesFor(config.keep_going.max_gait_seconds) : config.max_frames;
  }

  get fps() { return this.config.skeleton.fps; }

  get defaultCandidates() { return this.config.critic ? this.config.critic.candidates : 1; }

  framesFor(seconds) { return Math.max(1, roundHalfEven(seconds * this.fps)); }

  // The text's embedding (1, c): pooled vector, then the first token states when the model has
  // slots; for a 'minilm+sides' model, side-contrasted as text/sides.py does.
  async encode(text) {
    if (this.splitter) text = this.splitter.plainSubject(text); // as encode_text reads it
    if (this.memo.has(text)) return this.memo.get(text);
    const emb = await this.embed(text);
    const alpha = this.config.text_encoder.side_contrast || 0;
    const mirrored = alpha > 0 ? mirrorSides(text) : text;
    if (mirrored !== text) {
      const other = await this.embed(mirrored);
      for (let i = 0; i < emb.length; i++) emb[i] += alpha * (emb[i] - other[i]);
    }
    if (this.memo.size > 256) this.memo.delete(this.memo.keys().next().value);
    this.memo.set(text, emb);
    return emb;
  }

  async embed(text) {
    const ids = this.tokenizer.encode(text);
    const big = (values) => new ort.Tensor("int64", BigInt64Array.from(values, BigInt), [1, values.length]);
    const out = await this.sessions.text.run({ ids: big(ids), mask: big(ids.map(() => 1)) });
    const { token_slots: slots, dim } = this.config.text_encoder;
    const width = out.embedding.dims[1];
    const emb = new Float32Array(dim);
    emb.set(out.embedding.data);
    for (let k = 0; k < Math.min(slots, ids.length); k++) {
      emb.set(out.states.data.subarray(k * width, (k + 1) * width), (1 + k) * width);
    }
    return emb;
  }

  // sampling_times: K grid times from T down, stride n // K (Algorithm 2).
  times(steps) {
    const n = this.grid.length;
    const stride = Math.floor(n / steps);
    return Array.from({ length: steps }, (_, i) => this.grid[n - 1 - stride * i]);
  }

  logAlpha(t) {
    const { beta_min: b0, beta_max: b1 } = this.config.sampler;
    return -(t * t) * (b1 - b0) / 4 - t * b0 / 2; // Eq. 10
  }

  // The clean latents (rows * n * d) of one text, a row per noise stream (one batch), Algorithm 2
  // on S = c_skip x_t + c_out F (Eq. 11).
  async sample(cond, steps, noises) {
    const [n, d] = this.config.latent_shape;
    const { eta, time_scale: scale, clamp } = this.config.sampler;
    const rows = noises.length;
    const size = n * d;
    const times = this.times(steps);
    const texts = new Float32Array(rows * cond.length);
    for (let r = 0; r < rows; r++) texts.set(cond, r * cond.length);
    const text = new ort.Tensor("float32", texts, [rows, cond.length]);
    let x = new Float32Array(rows * size); // x_T, each row from its own stream
    noises.forEach((noise, r) => x.set(noise.normals(size), r * size));
    const x0 = new Float32Array(rows * size);
    for (let k = 0; k < times.length; k++) {
      const t = times[k];
      const { f } = await this.sessions.denoiser.run({
        x_t: new ort.Tensor("float32", x, [rows, n, d]), t: new ort.Tensor("float32", new Float32Array(rows).fill(t), [rows]), text });
      const st = scale * t;
      const skip = eta * eta / (st * st + eta * eta);
      const out = st / Math.sqrt(st * st + eta * eta);
      for (let i = 0; i < rows * size; i++) {
        const v = skip * x[i] + out * f.data[i];
        x0[i] = clamp === null ? v : Math.min(clamp, Math.max(-clamp, v));
      }
      if (k + 1 < times.length) { // re-noise to the next, lower time with fresh noise
        const la = this.logAlpha(times[k + 1]);
        const alpha = Math.exp(la);
        const sigma = Math.sqrt(-Math.expm1(2 * la));
        x = new Float32Array(rows * size);
        noises.forEach((noise, r) => {
          const z = noise.normals(size);
          for (let i = 0; i < size; i++) x[r * size + i] = alpha * x0[r * size + i] + sigma * z[i];
        });
      }
    }
    return x0;
  }

  // The seeds of a motion's candidates (pipeline.best_features): the first is the motion's own,
  // candidate k's seed + k * seed_stride (mod 2^63), as BigInts.
  candidateSeeds(seed, count) {
    const { seed_stride: stride, seed_modulus: modulus } = this.config.critic;
    return Array.from({ length: count }, (_, k) => (BigInt(seed) + BigInt(k) * BigInt(stride)) % BigInt(modulus));
  }

  // The clean latent (n * d) of one text: a single sample, or one of the best of `candidates` by
  // the critic (generate/compose/critic.py: the cosine of the latent's motion with the text).
  async bestLatent(cond, steps, seed, frames, candidates) {
    if (candidates <= 1 || !this.sessions.critic) return this.sample(cond, steps, [new PortableNoise(seed)]);
    const noises = this.candidateSeeds(seed, candidates).map((s) => new PortableNoise(s));
    const latents = await this.sample(cond, steps, noises);
    const [n, d] = this.config.latent_shape;
    const texts = new Float32Array(candidates * cond.length);
    for (let r = 0; r < candidates; r++) texts.set(cond, r * cond.length);
    const { score } = await this.sessions.critic.run({
      z: new ort.Tensor("float32", latents.map((v) => v / this.config.latent_scale), [candidates, 1, n * d]),
      frames: new ort.Tensor("float32", new Float32Array(candidates).fill(frames), [candidates]),
      text: new ort.Tensor("float32", texts, [candidates, cond.length]) });
    // the first candidate within the critic's margin of the best (critic.py pick)
    let top = score.data[0];
    for (let r = 1; r < candidates; r++) top = Math.max(top, score.data[r]);
    const floor = Math.fround(top - Math.fround(this.config.critic.margin ?? 0));
    let chosen = 0;
    while (score.data[chosen] < floor) chosen++;
    return latents.slice(chosen * n * d, (chosen + 1) * n * d);
  }

  // Denormalized features (frames * D) of a clean latent.
  async decode(latent, frames) {
    const [n, d] = this.config.latent_shape;
    const z = latent.map((v) => v / this.config.latent_scale);
    const valid = new ort.Tensor("bool", new Uint8Array(frames).fill(1), [1, frames]);
    const { features } = await this.sessions.decoder.run({ latent: new ort.Tensor("float32", z, [1, n, d]), valid });
    const { mean, std } = this.config.norm;
    const D = this.config.feature_dim;
    const out = new Float32Array(frames * D);
    for (let i = 0; i < out.length; i++) out[i] = features.data[i] * std[i % D] + mean[i % D];
    return out;
  }

  // The parts of a prompt that names actions in turn and the frames each is made with (its share
  // of the clip, plus the next part's blend), as generate() makes it (pipeline._made, _chained,
  // long_motion.generate_long); null for one action, or when a part would get less than
  // min_part_seconds.
  async plan(text, frames) {
    if (!this.splitter) return null;
    const parts = this.splitter.split(text);
    const { min_part_seconds: minPart, blend_seconds: blendSeconds } = this.config.sequence;
    const minFrames = this.framesFor(minPart);
    if (parts.length < 2 || Math.floor(frames / parts.length) < minFrames) return null;
    const vectors = [];
    if (this.durations) for (const part of parts) vectors.push(await this.encode(part)); // one run at a time
    const weights = this.durations ? this.durations.partWeights(vectors, frames / this.fps, minPart) : parts.map(() => 1);
    const share = splitFrames(weights, frames, minFrames);
    const blend = Math.max(2, roundHalfEven(blendSeconds * this.fps));
    return { parts, share, blend, lengths: share.map((n, k) => (k + 1 < share.length ? n + blend : n)) };
  }

  // One prompt as the model draws it: {features, joints} (feet as decoded).
  async draw(text, frames, steps, seed, timing, candidates = 1) {
    let mark = performance.now();
    const cond = await this.encode(text);
    timing.text_ms += performance.now() - mark;
    mark = performance.now();
    const latent = await this.bestLatent(cond, steps, seed, frames, candidates);
    timing.sample_ms += performance.now() - mark;
    mark = performance.now();
    const features = await this.decode(latent, frames);
    const joints = recoverFromRic(features, frames, this.config.feature_dim);
    timing.decode_ms += performance.now() - mark;
    return { features, joints, frames };
  }

  // One prompt given to the model whole, as generate() makes it (pipeline._made, _keep_going):
  // a one-action gait asked for clearly longer than its natural length that stopped early is
  // made again as takes of that length (take k with seed + k), chained into one continuing
  // motion (keepgoing.js); {features (null when kept going), joints, frames, takes}.
  async whole(text, frames, steps, seed, timing, candidates) {
    const window = this.config.max_frames;
    const made = await this.draw(text, Math.min(frames, window), steps, seed, timing, candidates);
    const kg = this.keepGoing;
    if (!kg || kg.namesAnEnd(text) || frames / this.fps < this.config.sequence.min_part_seconds
        || this.splitter.split(text).length > 1 || this.splitter.splitConcurrent(text) !== null) {
      if (frames > window) throw this.tooLong(frames, text);
      return made;
    }
    const natural = this.durations.partSeconds([await this.encode(text)])[0];
    if (frames > window) { // only a gait goes on past the window
      if (!kg.isGait(made.joints, window, natural)) throw this.tooLong(frames, text);
    } else if (!kg.stopsEarly(made.joints, frames, natural)) return made;
    const take = Math.min(this.framesFor(natural), this.config.max_frames);
    const blend = Math.max(2, roundHalfEven(this.config.sequence.blend_seconds * this.fps));
    const count = kg.segmentCount(frames, take, blend);
    for (const n of [count, 2 * count]) { // twice as many when the stretches fell short
      const takes = [];
      for (let k = 0; k < n; k++) takes.push(await this.draw(text, take, steps, seed + k, timing, candidates));
      const mark = performance.now();
      const chained = kg.chain(takes, frames, blend);
      timing.decode_ms += performance.now() - mark;
      if (chained) return { features: null, joints: chained.joints, frames, takes: n };
    }
    if (frames > window) throw this.tooLong(frames, text);
    return made; // the takes did not reach the length: as made
  }

  // The window's error for a prompt (or a part) asked for longer than it that cannot go on
  // (pipeline._too_long).
  tooLong(frames, text) {
    const window = this.config.max_frames;
    const gaits = this.keepGoing ? "; only a gait (a walk, a jog, a run...) keeps going past it, up to " +
      `${(this.longestGait / this.fps).toFixed(0)} s` : "";
    return new Error(`'${text}': ${(frames / this.fps).toFixed(1)} s is longer than the model's window ` +
      `(${(window / this.fps).toFixed(1)} s)${gaits}`);
  }

  // The seconds of a prompt given no length (pipeline.default_seconds): default_seconds, or
  // longer when the duration model says its actions take longer (a circle walk, two actions),
  // up to the window; the parts timed as they would be made (pipeline.auto_seconds).
  async defaultSeconds(text, split = true) {
    const longest = this.config.max_frames / this.fps;
    const flat = Math.min(this.config.default_seconds ?? 5, longest);
    if (!this.durations || !this.splitter) return flat;
    const pair = split ? this.splitter.splitConcurrent(text) : null;
    const body = pair ? pair[0] : text;
    const parts = split ? this.splitter.split(body) : [body];
    const vectors = [];
    for (const part of parts) vectors.push(await this.encode(part));
    const clip = this.durations.partSeconds(vectors).reduce((a, b) => a + b, 0);
    return Math.max(flat, Math.min(Math.max(clip, this.config.sequence.min_part_seconds), longest));
  }

  // A prompt's joints as decoded and joined, before the feet are planted: {features (null when
  // joined), joints, parts, seams}. As generate() makes it (pipeline._made): an arm action done
  // during another is made alone, standing, and its arms put on the body made from the rest
  // (pipeline._concurrent, both with the seed); a sequence one part each (part k with seed + k),
  // chained; anything else whole.
  async make(text, frames, steps, seed, timing, split, candidates) {
    const pair = split && this.splitter && this.config.skeleton.arm_joints ? this.splitter.splitConcurrent(text) : null;
    if (pair) {
      const body = await this.make(pair[0], frames, steps, seed, timing, split, candidates);
      const arms = await this.whole(pair[1], frames, steps, seed, timing, candidates);
      const mark = performance.now();
      const joints = reattach(arms.joints, body.joints, frames, this.config.skeleton.arm_joints, this.config.skeleton);
      timing.decode_ms += performance.now() - mark;
      return { features: null, joints, seams: body.seams,
        parts: [...body.parts, { text: pair[1], frames, seed, arms: true }] };
    }
    let mark = performance.now();
    const plan = split ? await this.plan(text, frames) : null;
    timing.text_ms += performance.now() - mark;
    if (!plan) {
      const { features, joints, takes } = await this.whole(text, frames, steps, seed, timing, candidates);
      return { features, joints, seams: [], parts: [{ text, frames, seed, ...(takes ? { takes } : {}) }] };
    }
    const made = [];
    for (let k = 0; k < plan.parts.length; k++) made.push(await this.whole(plan.parts[k], plan.lengths[k], steps, seed + k, timing, candidates));
    mark = performance.now();
    const { joints, seams } = chainSegments(made, plan.blend, this.config.skeleton);
    timing.decode_ms += performance.now() - mark;
    return { features: null, joints, seams, parts: plan.parts.map((p, k) => ({ text: p, frames: plan.share[k], seed: seed + k })) };
  }

  // One motion: {text, seed, nfe, frames, features (null when joined from parts), joints
  // (frames * J * 3), parts [{text, frames, seed, arms}], seams, timing (ms)}; split false gives
  // the model the whole prompt at once; frames null (or left out): defaultSeconds; candidates:
  // each prompt (or part) the best of this many samples by the critic, null the model's default
  // (8 for the bundled model, as mlct generate), 1 plain sampling.
  async generate({ text, frames = null, nfe, seed, split = true, candidates = null }) {
    const start = performance.now();
    const clean = cleanPrompt(text, this.config.max_prompt_chars);
    const { max_frames: maxFrames } = this.config;
    const { max_nfe: maxNfe, default_nfe: defaultNfe } = this.config.sampler;
    const steps = nfe ?? defaultNfe; // the request checked before any network runs
    if (!Number.isInteger(steps) || steps < 1 || steps > maxNfe) throw new Error(`nfe must be within 1..${maxNfe}, got ${steps}`);
    if (!Number.isSafeInteger(seed) || seed < 0) throw new Error(`seed must be a whole number >= 0, got ${seed}`);
    const count = candidates ?? this.defaultCandidates;
    const most = this.config.critic ? this.config.critic.max_candidates : 1;
    if (!Number.isInteger(count) || count < 1 || count > most) {
      throw new Error(this.config.critic ? `candidates must be within 1..${most}, got ${count}`
        : "this model has no critic to choose among candidates, so candidates must be 1");
    }
    // "... for 8 seconds" (pipeline.stated_lengths): the model reads the prompt without the
    // phrase, whose seconds are the length unless one is given; in a prompt of several actions
    // it stays where it is (whose duration it gives is not clear)
    let [model, stated] = this.stated ? this.stated.read(clean) : [clean, null];
    if (stated !== null && split && this.splitter && this.splitter.split(model).length > 1) {
      [model, stated] = [clean, null];
    }
    if (frames === null && stated !== null) frames = this.framesFor(stated);
    // past the window only a one-action gait goes on (whole() says so otherwise)
    const longest = this.longestGait;
    if (frames !== null && (!Number.isInteger(frames) || frames < 1 || frames > longest)) {
      throw new Error(`length ${frames} frames is outside 1..${longest} (${(longest / this.fps).toFixed(2)} s at ${this.fps} fps)`);
    }
    const timing = { text_ms: 0, sample_ms: 0, decode_ms: 0 };
    if (frames === null) frames = this.framesFor(await this.defaultSeconds(model, split)); // within the window
    timing.text_ms += performance.now() - start; // the length's text-encoder runs, if any
    const made = await this.make(model, frames, steps, seed, timing, split, count);
    const mark = performance.now();
    // planted feet, as the Python pipeline's (a site made before it has no foot_lock)
    const joints = this.config.foot_lock ? lockFeet(made.joints, frames, this.config.skeleton, this.config.foot_lock) : made.joints;
    const end = performance.now();
    timing.decode_ms += end - mark;
    timing.total_ms = end - start;
    return { text: clean, seed, nfe: steps, frames, candidates: count, features: made.features, joints,
      parts: made.parts, seams: made.seams, skeleton: this.config.skeleton, footLock: this.config.foot_lock, timing };
  }
}
