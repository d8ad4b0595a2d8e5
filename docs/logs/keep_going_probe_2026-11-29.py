"""How often a gait asked for 12 s keeps going (no error, moving in its last 2 s), per model."""
import sys, numpy as np, mlct
from mlct.errors import MlctError
from mlct.generate.keep_going import ground_speed
prompts = ["a person walks forward", "a person jogs forward", "a person runs forward",
           "a person walks backwards", "someone walks in a circle", "a man walks slowly"]
for m in sys.argv[2:]:
    g = mlct.load(None if m == "bundled" else m)
    ok = err = stood = 0
    for p in prompts:
        for seed in range(8):
            try:
                j = np.asarray(g.generate(p, seconds=float(sys.argv[1]), seed=seed).joints)[0]
            except MlctError:
                err += 1; continue
            if ground_speed(j, 20)[-40:].mean() < 0.2: stood += 1
            else: ok += 1
    print(m, f"{len(prompts) * 8} gait prompts x seeds at {sys.argv[1]} s: kept going {ok}, refused {err}, stood still at the end {stood}")
