"""Neural networks of mlct (no schedules, no datasets)."""
