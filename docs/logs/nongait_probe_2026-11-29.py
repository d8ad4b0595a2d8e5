"""Non-gait prompts asked for 12 s: each should be refused (only a gait goes past the window)."""
import sys, numpy as np, mlct
from mlct.errors import MlctError
prompts = ["a person jumps forward", "a person does a long jump", "a person jumps up and down",
           "a person turns around", "a person spins in place", "a person kicks with the left leg",
           "a person hops forward on the right foot", "a person side steps to the left"]
for m in sys.argv[1:]:
    g = mlct.load(m)
    kept = []
    for p in prompts:
        for seed in range(4):
            try:
                g.generate(p, seconds=12, seed=seed); kept.append((p, seed))
            except MlctError:
                pass
    print(m, f"{len(prompts) * 4} non-gait prompts x seeds at 12 s: kept going {len(kept)}", kept[:8])
