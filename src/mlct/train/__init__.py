"""Training engine: one readable loop, resumable atomic checkpoints, EMA, DDP."""
