// The portable noise of mlct.generate.samplers.portable_noise (its docstring says why): a counter-based
// stream of 32-bit words, lowbias32(key ^ lowbias32(i)), two words per 53-bit uniform, Box-Muller
// pairs in float64 stored as float32. Same seed, same numbers as the Python side.
"use strict";

const SALT = 0x9e3779b9;

function mix(x) {
  x >>>= 0;
  x ^= x >>> 16;
  x = Math.imul(x, 0x7feb352d) >>> 0;
  x ^= x >>> 15;
  x = Math.imul(x, 0x846ca68b) >>> 0;
  x ^= x >>> 16;
  return x >>> 0;
}

export class PortableNoise {
  // seed: a whole number in 0 .. 2^53 - 1 (a JS number), or a BigInt in 0 .. 2^63 - 1 as Python
  // takes (a best-of-N candidate's seed, model.js).
  constructor(seed) {
    let lo;
    let hi;
    if (typeof seed === "bigint") {
      if (seed < 0n || seed >= 1n << 63n) throw new Error(`seed must lie in 0..2^63 - 1, got ${seed}`);
      lo = Number(seed & 0xffffffffn);
      hi = Number(seed >> 32n);
    } else {
      if (!Number.isSafeInteger(seed) || seed < 0) throw new Error(`seed must be a whole number >= 0, got ${seed}`);
      lo = seed % 4294967296;
      hi = Math.floor(seed / 4294967296);
    }
    this.key = mix((mix((hi ^ SALT) >>> 0) ^ lo) >>> 0);
    this.counter = 0;
  }

  word() {
    const w = mix((this.key ^ mix(this.counter)) >>> 0);
    this.counter += 1;
    return w;
  }

  // count normals in a new Float32Array; an odd count still uses a whole pair of draws.
  normals(count) {
    const out = new Float32Array(count);
    for (let i = 0; i < count; i += 2) {
      const [a, b, c, d] = [this.word(), this.word(), this.word(), this.word()];
      const u1 = ((a >>> 5) * 67108864 + (b >>> 6) + 0.5) / 9007199254740992;
      const u2 = ((c >>> 5) * 67108864 + (d >>> 6) + 0.5) / 9007199254740992;
      const radius = Math.sqrt(-2 * Math.log(u1));
      out[i] = radius * Math.cos(2 * Math.PI * u2);
      if (i + 1 < count) out[i + 1] = radius * Math.sin(2 * Math.PI * u2);
    }
    return out;
  }
}
