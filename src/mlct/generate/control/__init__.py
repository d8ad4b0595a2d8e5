"""Controls: the schema of paths, keyframes, edits and prefixes (schema.py), reading them from
files (files.py), how a motion meets them (controlled.py) and the motion-space corrections
(fit.py); docs/control.md."""
