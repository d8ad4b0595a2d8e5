// A prompt that names actions in turn ("walks forward, then waves"), split into one prompt per
// action, and each part's share of the clip: the page's port of generate/compose/actions.py's
// split_actions and generate/compose/durations.py's part_weights and split_frames. The word lists and
// patterns are Python's, read from model.json ("sequence.rules": compose.portable_rules), so
// only the steps are written here; tests/test_web_static_e2e.py compares the parts and the
// shares with Python's on the benchmark's captions and hand-written prompts.
"use strict";

// Python's str.strip(chars)
function strip(text, chars) {
  let a = 0;
  let b = text.length;
  while (a < b && chars.includes(text[a])) a++;
  while (b > a && chars.includes(text[b - 1])) b--;
  return text.slice(a, b);
}

const PUNCT = " ,;.";
const words = (text) => text.split(/\s+/).filter((w) => w); // Python's str.split()

// Python's pattern.split(text, maxsplit=1): JS's split limit drops the rest instead of keeping it.
function splitOnce(pattern, text) {
  const found = pattern.exec(text);
  return found ? [text.slice(0, found.index), text.slice(found.index + found[0].length)] : [text];
}

export class ActionSplitter {
  constructor(rules) {
    const flags = (name) => (["listed", "gerund_word", "and"].includes(name) ? "giu" : "iu"); // u: Unicode case folding, as Python's
    this.re = {};
    for (const [name, source] of Object.entries(rules.patterns)) this.re[name] = new RegExp(source, flags(name));
    this.forms = new Map(Object.entries(rules.verb_forms)); // lemma -> [third person, gerund]
    this.third = new Map();
    this.gerund = new Map();
    for (const [lemma, [third, gerund]] of this.forms) { this.third.set(third, lemma); this.gerund.set(gerund, lemma); }
    this.returnVerbs = new Set(rules.return_verbs);
    this.returnWords = new Set(rules.return_words);
    this.pairs = new Set(rules.one_action_pairs.map(([a, b]) => `${a} ${b}`));
    this.adverbs = new Set(rules.adverbs);
    this.armVerbs = new Set(rules.arm_verbs);
    this.defaultSubject = rules.default_subject;
    this.trainedSubjects = new Set(rules.trained_subjects ?? []);
    this.bodyWords = new Set(rules.body_words ?? []);
    this.verbHalves = new Set(rules.verb_halves ?? []);
    this.directionWords = new Set(rules.direction_words ?? []);
    this.minWords = rules.min_words;
  }

  // split_actions: the parts of a prompt that names actions in sequence; [text] when it names one.
  split(text) {
    let parts = this.inOrder(text).split(this.re.sequence).map((p) => strip(p, PUNCT));
    parts = this.returnsJoined(parts.filter((p) => words(p).length >= this.minWords));
    parts = parts.flatMap((p) => this.splitListed(p));
    if (parts.length < 2) return [text];
    const found = this.re.subject.exec(parts[0]);
    const subject = found ? found[0] : this.defaultSubject;
    return [parts[0], ...parts.slice(1).map((p) => (this.re.subject.test(p) ? p : `${subject} ${this.finiteLead(p)}`))];
  }

  // split_concurrent: [the body's prompt, the arms' prompt] of a prompt that names an arm action
  // done during another ("walks forward while waving"), or null. The body's prompt may still be
  // a sequence; the arms' prompt gets the text's subject.
  splitConcurrent(text) {
    const pieces = text.split(new RegExp(`(${this.re.sequence.source})`, "iu"));
    for (let k = 0; k < pieces.length; k += 2) { // the phrases; odd indices are the separators
      const split = this.splitPhrase(pieces[k]);
      if (split === null) continue;
      let [body, arms] = split;
      const found = this.re.subject.exec(text.trim());
      const subject = found ? found[0] : this.defaultSubject;
      if (!this.re.subject.test(arms)) arms = `${subject} ${arms}`;
      if (k > 0 && body.startsWith(subject)) body = body.slice(subject.length).trim();
      return [[...pieces.slice(0, k), body, ...pieces.slice(k + 1)].join("").trim(), arms];
    }
    return null;
  }

  splitPhrase(phrase) { // [body, arms] of one phrase naming two actions at once, or null
    const pairs = [];
    phrase = strip(phrase, PUNCT);
    if (this.re.while.test(phrase)) {
      const [first, second] = splitOnce(this.re.while, phrase);
      pairs.push([first, this.finite(second)]);
    } else if (this.re.same_time.test(phrase)) {
      const both = phrase.replace(this.re.same_time, "");
      for (const m of both.matchAll(this.re.and)) {
        pairs.push([both.slice(0, m.index), this.finiteLead(both.slice(m.index + m[0].length))]);
      }
    }
    for (let [first, second] of pairs) {
      first = strip(first, PUNCT);
      second = strip(second, PUNCT);
      if (!first || !second) continue;
      // both sides must start with a verb we know: "waves while smiling" is one action
      if (this.firstVerb(first) === null || this.firstVerb(second) === null) continue;
      const [armsFirst, armsSecond] = [this.isArmAction(first), this.isArmAction(second)];
      if (armsSecond && !armsFirst) return [first, second];
      if (armsFirst && !armsSecond) {
        const subject = this.withoutSubject(first)[0];
        return [subject ? `${subject} ${second}` : second, first];
      }
    }
    return null;
  }

  // compose.plain_subject: a subject the training captions never used ("the robot") read as
  // the default one; none, a trained one or a body part ("the left arm") left as it is
  plainSubject(text) {
    if (!this.trainedSubjects.size) return text;
    const found = this.re.subject.exec(text);
    if (!found) return text;
    const list = words(found[0].toLowerCase());
    // a trained subject, or one followed by half a two-word verb ("a man power walks"), stays
    const trained = list.map((_, k) => k + 1).filter((k) => this.trainedSubjects.has(list.slice(0, k).join(" ")));
    const last = trained.length ? trained[trained.length - 1] : 0;
    if (list.some((w) => this.bodyWords.has(w)) || (last && (last === list.length || this.verbHalves.has(list[last])))) return text;
    return this.defaultSubject + text.slice(found[0].length);
  }

  firstVerb(phrase) { return this.leadingVerb(this.withoutSubject(phrase)[1]); }

  isArmAction(phrase) { return this.armVerbs.has(this.firstVerb(phrase)); }

  lemma(word) {
    const w = word.toLowerCase();
    return this.third.get(w) ?? this.gerund.get(w) ?? (this.forms.has(w) ? w : null);
  }

  withoutSubject(phrase) {
    const found = this.re.subject.exec(phrase);
    return found ? [found[0], phrase.slice(found[0].length).trim()] : ["", phrase];
  }

  leadingWord(piece) { // past two adverbs: "is slowly walking" -> "walking"
    let list = words(piece.toLowerCase());
    for (let i = 0; i < 2; i++) {
      if (list.length > 1 && (list[0].endsWith("ly") || this.adverbs.has(list[0]))) list = list.slice(1);
    }
    return list.length ? list[0] : "";
  }

  leadingVerb(piece) {
    const word = this.leadingWord(piece);
    if (!word || word === "back") return null; // "walks forward and back": a direction
    return this.lemma(word);
  }

  finiteLead(phrase) { // "jogging forward" -> "jogs forward"
    const space = phrase.indexOf(" ");
    const [head, tail] = space < 0 ? [phrase, ""] : [phrase.slice(0, space), phrase.slice(space + 1)];
    const lemma = this.gerund.get(head.toLowerCase());
    return lemma ? `${this.forms.get(lemma)[0]} ${tail}`.trim() : phrase;
  }

  finite(phrase) { // every gerund made finite
    return phrase.replace(this.re.gerund_word, (word) => {
      const lemma = this.gerund.get(word.toLowerCase());
      return lemma ? this.forms.get(lemma)[0] : word;
    });
  }

  onlyReturns(phrase) {
    const list = phrase.toLowerCase().match(/[a-z]+/g) ?? [];
    return list.length > 0 && this.returnVerbs.has(this.lemma(list[0])) && list.slice(1).every((w) => this.returnWords.has(w));
  }

  returnsJoined(parts) { // "squats, then stands back up" is one squat
    const out = [];
    for (const part of parts) {
      const list = part.toLowerCase().match(/[a-z]+/g) ?? [];
      if (out.length && list.length && list.every((w) => this.directionWords.has(w))) { // "leans left and then right"
        out[out.length - 1] = `${out[out.length - 1]}, then ${part}`;
        continue;
      }
      const [head, ...tail] = splitOnce(new RegExp(this.re.listed.source, "iu"), this.withoutSubject(part)[1]);
      if (out.length && this.re.lowering.test(out[out.length - 1]) && this.onlyReturns(head)) {
        out[out.length - 1] = `${out[out.length - 1]}, then ${head}`;
        out.push(...tail.filter((t) => t.trim()));
        continue;
      }
      out.push(part);
    }
    return out;
  }

  splitListed(phrase) { // "claps twice and jabs with the right arm": one piece per action
    if (this.re.while.test(phrase) || this.re.same_time.test(strip(phrase, PUNCT))) return [phrase];
    const [subject, rest] = this.withoutSubject(phrase);
    const pieces = rest.split(this.re.listed);
    const separators = [...rest.matchAll(this.re.listed)].map((m) => m[0]);
    let current = this.leadingVerb(pieces[0]);
    if (current === null) return [phrase];
    const finite = this.third.has(this.leadingWord(pieces[0]));
    const actions = [pieces[0]];
    separators.forEach((separator, i) => {
      const piece = pieces[i + 1];
      const verb = this.leadingVerb(piece);
      const opensStanding = actions.length === 1 && this.returnVerbs.has(current);
      // after a finite verb, a comma and a gerund say how ("sidesteps along the line, going right")
      const manner = finite && separator.includes(",") && this.gerund.has(this.leadingWord(piece));
      if (verb === null || this.returnVerbs.has(verb) || this.pairs.has(`${current} ${verb}`) || opensStanding || manner) {
        if (opensStanding && verb !== null) current = verb;
        actions[actions.length - 1] += separator + piece;
        return;
      }
      actions.push(piece);
      current = verb;
    });
    if (actions.length === 1) return [phrase];
    return [subject ? `${subject} ${actions[0]}` : actions[0], ...actions.slice(1)];
  }

  // in_order: "turns left after walking forward" -> "a person walks forward, then turns left"
  inOrder(text) {
    let word;
    let clause;
    let main;
    let found = this.re.clause_first.exec(text);
    if (found) [, word, clause, main] = found;
    else {
      found = this.re.clause_last.exec(text);
      if (!found) return text;
      [, main, word, clause] = found;
    }
    if (this.leadingVerb(strip(clause, PUNCT)) === null) return text; // "before the door": no action
    clause = this.finite(strip(clause, PUNCT));
    main = strip(main, PUNCT);
    let [subject, rest] = this.withoutSubject(main);
    subject = subject || this.defaultSubject;
    const [first, then] = word.toLowerCase() === "after" ? [clause, rest || main] : [rest || main, clause];
    return `${subject} ${first}, then ${then}`;
  }
}

// generate/compose/durations.py's DurationModel (model.json "durations"): log seconds from a part's text
// vector, a share per place in the sequence, and the weights split_frames shares a clip by.
export class Durations {
  constructor(spec) { this.spec = spec; }

  seconds(vector) {
    const { weight, bias, hidden_weight: hw, hidden_bias: hb } = this.spec;
    let x = Array.from(vector);
    if (hw) x = hb.map((b, k) => Math.tanh(x.reduce((sum, v, i) => sum + v * hw[i][k], 0) + b));
    return Math.exp(x.reduce((sum, v, i) => sum + v * weight[i], 0) + bias);
  }

  partSeconds(vectors) {
    const seconds = vectors.map((v) => this.seconds(v));
    if (seconds.length === 1) return [seconds[0] + this.spec.single_extra];
    const place = (i) => (i === 0 ? "first" : i === seconds.length - 1 ? "last" : "middle");
    return seconds.map((s, i) => Math.max(s + (this.spec.offsets[place(i)] ?? 0), this.spec.min_weight));
  }

  partWeights(vectors, totalSeconds, minSeconds) {
    if (!this.spec.offsets) return vectors.map((v) => this.seconds(v)); // a version 1 model
    const wanted = this.partSeconds(vectors);
    const sum = wanted.reduce((a, b) => a + b, 0);
    const fastest = this.spec.fastest_tempo_share;
    const shares = totalSeconds < fastest * sum
      ? squeezeLongestFirst(wanted.map((w) => fastest * w), totalSeconds)
      : wanted.map((w) => (w * totalSeconds) / sum);
    return shares.map((s) => Math.max(s - minSeconds, this.spec.min_weight));
  }
}

// durations.squeeze_longest_first: a short clip's time taken from the longest parts first.
export function squeezeLongestFirst(wanted, totalSeconds) {
  const levels = [...wanted].sort((a, b) => a - b);
  let below = 0;
  for (let k = 0; k < levels.length; k++) {
    const cap = (totalSeconds - below) / (levels.length - k);
    if (cap <= levels[k]) return wanted.map((w) => Math.min(w, cap));
    below += levels[k];
  }
  const sum = wanted.reduce((a, b) => a + b, 0);
  return wanted.map((w) => (w * totalSeconds) / sum);
}

// durations.split_frames: frames shared in proportion to the weights, each part at least
// minFrames when the total allows, the frames rounding left going to the largest remainders.
export function splitFrames(weights, frames, minFrames) {
  const count = weights.length;
  const floor = Math.min(minFrames, Math.floor(frames / count));
  const spare = frames - floor * count;
  const sum = weights.reduce((a, b) => a + b, 0);
  const exact = weights.map((w) => (spare * w) / sum);
  const share = exact.map((e) => floor + Math.floor(e));
  let left = frames - share.reduce((a, b) => a + b, 0);
  const order = exact.map((e, i) => [-(e - Math.floor(e)), i]).sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  for (const [, i] of order) { if (left-- <= 0) break; share[i] += 1; }
  return share;
}

// prompts.stated_seconds (model.json "stated": its pattern, number words and units): [the text
// without a phrase that says how long, the seconds it says], or [text, null] when it says none
// or more than one ("walks for 5 seconds, then waves for 3 seconds": whose is whose is the
// parts').
export class StatedSeconds {
  constructor(spec) {
    this.pattern = new RegExp(spec.pattern.replaceAll("(?P<", "(?<"), "gi");
    this.numbers = spec.numbers;
    this.units = spec.units;
  }

  read(text) {
    const found = [...text.matchAll(this.pattern)];
    if (found.length !== 1) return [text, null];
    const [match] = found;
    const number = match.groups.n.toLowerCase();
    const amount = /^[0-9]/.test(number) ? parseFloat(number) : this.numbers[number];
    const unit = match.groups.unit.toLowerCase().replace(/s+$/, "") || "s";
    const seconds = amount * this.units[unit];
    const rest = strip(text.slice(0, match.index) + text.slice(match.index + match[0].length), " ,;");
    if (!(seconds > 0) || !rest) return [text, null];
    return [words(rest).join(" "), seconds];
  }
}
