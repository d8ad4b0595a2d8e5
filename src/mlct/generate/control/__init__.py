"""Controls: the schema of paths, keyframes, edits and prefixes (schema.py), reading them from
files (files.py), how a motion meets them (controlled.py: a path walked by the text's own
motion re-timed to it, pace.py; the rest sampled, sampled.py; steering inside the sampling
steps, steered.py; in the control's world, world.py) and the motion-space corrections (fit.py);
docs/control.md."""
