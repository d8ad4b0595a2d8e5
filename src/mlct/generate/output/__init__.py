"""What generate() returns (generated.py: GeneratedMotion, Generation) and one writer per
output format (exports.py)."""
