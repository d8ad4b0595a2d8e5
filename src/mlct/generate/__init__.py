"""The inference wing: from a model bundle and text to motions and files.

- core.py: `MotionCore`, text -> latents -> features -> joints, one batch a call, its networks
  behind the backend interface (backends/: torch, onnx, cuda graphs);
- compose/: the prompt composer, `MotionGenerator`, which makes what generate() asks of
  prompts (their actions, lengths, best of N, gaits that keep going, chains) from the core;
- control/: paths, keyframes, edits and prefixes, and how a motion meets them;
- samplers/: the samplers as objects and their registry; bundle.py: the bundle format;
- output/: what a call returns and one writer per format; files.py: `mlct generate`'s files;
- load.py: `mlct.load`, a backend by name.

Import order: docs/architecture.md ("generate"). This package reads bundles and never imports
train/ (train/ writes runs and exports them into bundles). Nothing here is imported by
`import mlct`; `mlct.load` imports it on first use.
"""
