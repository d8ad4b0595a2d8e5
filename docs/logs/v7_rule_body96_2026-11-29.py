"""The version-6 rule's bars and limits, applied to version 7 (the 96/96 decoder) against
version 6 (the bundle), both evaluated in this session (/work/runs/ev, tags v7 and v6again)."""
import re, sys, statistics
ev = "/work/runs/ev"
V5 = {"captions": (0.942, 0.927), "side": (0.948, 0.927), "two": (0.980, 0.930),
      "heldout": ((0.876+0.902+0.796+0.852+0.810+0.686+0.752)/7, (0.833+0.884+0.762+0.810+0.833+0.671+0.752)/7)}
BUNDLE_WEAK = 1

def mq(tag):
    text = open(f"{ev}/mq_{tag}.txt").read()
    head = None; fam = {}; rows = {}
    for line in text.splitlines():
        if line.startswith("family"):
            head = ["ground truth", "captions", "paraphrases", "held-out para", "held-out 2", "held-out 3", "two actions", "two, halves", "two, whole"]
            continue
        parts = re.split(r"\s{2,}", line.strip())
        if head and len(parts) == len(head) + 1:
            rows.setdefault(parts[0], [float(x) if x != "nan" else float("nan") for x in parts[1:]])
    cols = {h: i for i, h in enumerate(head)}
    fams = {k: v for k, v in rows.items() if k not in ("OVERALL", "named side", "+ concurrent", "one action", "sequence", "motions")}
    c = cols["captions"]
    clf = float(re.search(r"exact_set_accuracy ([0-9.]+)", text).group(1))
    low = min(fams.items(), key=lambda kv: kv[1][c])
    return {"captions": rows["OVERALL"][c], "side": rows["named side"][c], "low": (low[0], low[1][c]),
            "para": rows["OVERALL"][cols["paraphrases"]], "two": rows["OVERALL"][cols["two actions"]],
            "clf": clf}

def heldout(tag):
    vals = {}
    for line in open(f"{ev}/para_{tag}.txt"):
        m = re.search(r"held-out (\d)\s+([0-9.]+) \|", line)
        if m: vals[int(m.group(1))] = float(m.group(2))
    return vals

def readme(tag):
    m = re.search(r"all: (\d+)/(\d+)", open(f"{ev}/readme_{tag}.txt").read()); return int(m.group(1))

def weak(tag):
    m = re.search(r"a side under half its seeds: (\d+)(.*)", open(f"{ev}/sided_{tag}.txt").read())
    return int(m.group(1)), m.group(2).strip()

res = {}
ok = True
for tag in ("v7c", "v6s67"):
    r = mq(tag); h = heldout(tag); r["heldout"] = statistics.mean(h[i] for i in range(1, 8)); r["h"] = h
    r["readme"] = readme(tag); r["weak"] = weak(tag); res[tag] = r
    bars = {"captions>=0.85": r["captions"] >= 0.85, "family>=0.60": r["low"][1] >= 0.60,
            "paraphrases>=0.70": r["para"] >= 0.70, "two>=0.60": r["two"] >= 0.60,
            "side>=0.90": r["side"] >= 0.90, "classifier>=0.80": r["clf"] >= 0.80,
            "readme>=22": r["readme"] >= 22, f"weak<={BUNDLE_WEAK}": r["weak"][0] <= BUNDLE_WEAK}
    print(tag, {k: v for k, v in r.items()})
    print("  bars:", bars)
    if tag == "v7c":
        ok &= all(bars.values())
for key, limit in (("captions", 0.03), ("side", 0.03), ("heldout", 0.02), ("two", 0.02)):
    a, b = res["v7c"][key], res["v6s67"][key]
    good = a >= b - limit - 1e-9
    print(f"{key}: v7 {a:.4f} v6 {b:.4f} diff {a - b:+.4f} (may lose {limit}) {'ok' if good else 'FAIL'}")
    ok &= good
print("RULE:", "v7 passes" if ok else "v7 does not pass")
