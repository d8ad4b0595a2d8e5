// BERT WordPiece tokenization as the `tokenizers` library runs MiniLM's tokenizer.json
// (BertNormalizer: clean text, CJK spacing, accents stripped, lower case; BertPreTokenizer:
// whitespace and punctuation; WordPiece, longest match first, "##" continuations; [CLS] ... [SEP],
// truncated to max_length). mlct export-web checks that tokenizer.json asks for exactly these
// steps; tests/test_web_static_e2e.py compares the ids with the Python tokenizer on many texts.
"use strict";

const CJK = [[0x4e00, 0x9fff], [0x3400, 0x4dbf], [0x20000, 0x2a6df], [0x2a700, 0x2b73f],
  [0x2b740, 0x2b81f], [0x2b920, 0x2ceaf], [0xf900, 0xfaff], [0x2f800, 0x2fa1f]];
const OTHER = /\p{C}/u; // control, format, unassigned, private use, surrogates
const WHITE = /\s/u;
const MARK = /\p{Mn}/u;
const PUNCT = /[!-/:-@[-`{-~]|\p{P}/u; // ASCII punctuation, or any Unicode punctuation

const isCjk = (code) => CJK.some(([lo, hi]) => code >= lo && code <= hi);
// Rust's char::is_whitespace is Unicode White_Space; JS \s adds U+FEFF, which is "other" (Cf).
const isSpace = (ch) => ch !== "\ufeff" && WHITE.test(ch);

function normalize(text) {
  let out = "";
  for (const ch of text) {
    // as tokenizers: controls go first (\v, \f, U+0085 too, though white space), then spaces
    if (ch === "\0" || ch === "\ufffd") continue;
    const tab = ch === "\t" || ch === "\n" || ch === "\r";
    if (!tab && OTHER.test(ch)) continue;
    if (tab || isSpace(ch)) { out += " "; continue; }
    out += isCjk(ch.codePointAt(0)) ? ` ${ch} ` : ch;
  }
  let stripped = "";
  for (const ch of out.normalize("NFD")) if (!MARK.test(ch)) stripped += ch;
  let lower = "";
  for (const ch of stripped) lower += ch.toLowerCase(); // one character at a time, as Rust
  return lower;
}

function preTokenize(text) {
  const words = [];
  let word = "";
  for (const ch of text) {
    if (isSpace(ch)) {
      if (word) words.push(word);
      word = "";
    } else if (PUNCT.test(ch)) {
      if (word) words.push(word);
      words.push(ch);
      word = "";
    } else {
      word += ch;
    }
  }
  if (word) words.push(word);
  return words;
}

export class WordPieceTokenizer {
  // vocab: the lines of vocab.txt (id = line number); settings: model.json's text_encoder.
  constructor(vocabText, settings) {
    this.vocab = new Map();
    vocabText.split("\n").forEach((word, id) => {
      const w = word.replace(/\r$/, "");
      if (w !== "" || id === 0) this.vocab.set(w, id);
    });
    this.settings = settings;
    // special tokens are found in the raw text first, longest first, as tokenizers does
    this.special = Object.keys(settings.special_tokens).sort((a, b) => b.length - a.length);
  }

  wordPiece(word, ids) {
    const chars = Array.from(word);
    if (chars.length > this.settings.max_input_chars_per_word) { ids.push(this.settings.unk); return; }
    const pieces = [];
    for (let start = 0; start < chars.length;) {
      let end = chars.length;
      let found = -1;
      while (start < end) {
        const piece = (start > 0 ? "##" : "") + chars.slice(start, end).join("");
        const id = this.vocab.get(piece);
        if (id !== undefined) { found = id; break; }
        end -= 1;
      }
      if (found < 0) { ids.push(this.settings.unk); return; }
      pieces.push(found);
      start = end;
    }
    ids.push(...pieces);
  }

  // The text's ids without [CLS] / [SEP].
  tokens(text) {
    const ids = [];
    let rest = "";
    const flush = () => {
      for (const word of preTokenize(normalize(rest))) this.wordPiece(word, ids);
      rest = "";
    };
    for (let i = 0; i < text.length;) {
      const special = this.special.find((s) => text.startsWith(s, i));
      if (special) {
        flush();
        ids.push(this.settings.special_tokens[special]);
        i += special.length;
      } else {
        rest += text[i];
        i += 1;
      }
    }
    flush();
    return ids;
  }

  // [CLS] tokens [SEP], at most max_length ids.
  encode(text) {
    const ids = this.tokens(text).slice(0, this.settings.max_length - 2);
    return [this.settings.cls, ...ids, this.settings.sep];
  }
}
