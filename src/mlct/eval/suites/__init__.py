"""The quality suites that bench/quality.py runs: each module has `add_arguments(parser)` and
`run(args)`, where args also carries `prompt_dir` (the hand-written prompt sets, bench/data),
`error` (the parser's one-line error) and, for `motion` and `real`, `load_autoencoder(path)`.

- motion: the benchmark's test captions, paraphrases and two-action prompts, per family and
  side; the autoencoder's reconstructions; the action classifier (common.py: the shared judge);
- paraphrases: the hand-written sets, several models side by side;
- sides: the plainest left and right prompt of every sided family;
- examples: five example prompts; short: bare verbs ("a woman waves"); turns: turn sizes;
- feet: planted feet off and on; keep-going: a gait asked for longer than it lasts;
- int8: how far onnx-int8 moves the joints from float32's;
- real: real capture's reconstructions, a model's variety and foot skating against the data's;
- ground-truth: the read-outs on their own procedural ground truth, per family.
"""

from __future__ import annotations

# the command name -> the module
SUITES = {"motion": "motion", "paraphrases": "paraphrases", "sides": "sides",
          "examples": "examples", "short": "short", "turns": "turns", "feet": "feet",
          "keep-going": "keep_going", "int8": "int8", "real": "real",
          "ground-truth": "ground_truth"}
