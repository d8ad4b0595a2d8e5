"""What generate() makes of a prompt, above the core's one batch of samples: its reading
(prompts.py, actions.py), its length (durations.py), best of N (critic.py), a far prompt's pull
(text_anchors.py, unknown_prompts.py), gaits that keep going (keep_going.py), chains
(long_motion.py) and one batch for a whole list (batch_plan.py); generator.py puts them
together in MotionGenerator."""
