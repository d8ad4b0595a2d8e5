"""The inference wing: from a model bundle and text to motions and files.

- bundle.py: the bundle format (`mlct export` writes it through train/export.py, this reads it);
- pipeline.py: `MotionGenerator`, a loaded model: text encoder, sampler, decoder;
- samplers/: the samplers as objects (consistency, DDIM + CFG), one file each, and the registry
  that turns a bundle's sampler name into one;
- generated.py: `GeneratedMotion` / `Generation`, what a call returns;
- exports.py: one writer per output format (.gif .mp4 .png .npy .json .bvh);
- long_motion.py: several prompts chained into one long motion;
- prompts.py: prompt cleaning and prompt files;
- files.py: what `mlct generate` writes for a request.

Import order: this package reads bundles and never imports train/ (train/ writes runs and
exports them into bundles). Nothing here is imported by `import mlct`; `mlct.load` imports it
on first use.
"""
