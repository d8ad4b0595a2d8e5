#!/usr/bin/env bash
# The bundled model's decoder fine-tuned on a lent GPU (its encoder frozen, so stage 2's latents
# keep their meaning and the bundle's denoiser stays valid): the recipe's last decoder stage
# (trajectory term, latent noise 0.3, held past the end) for STEPS x 128 motions at lr 1e-4 with
# train.ae.cuda_graph=true, where the recipe ran 3,000 x 32 on the CPU. The weights come back
# as $OUT/decoder_tune.safetensors (float16, the checkpoint's tensors) and its log.
#
#   bash bench/gpu_decoder_tune.sh [CARRY_DIR] [STEPS] [SECONDS]   (.devcarry 15000 125)
set -u
cd "$(dirname "$0")/.."
final=${OUT:-/tmp/gpu_decoder_tune}
export OUT=/tmp/decoder_tune_out
source bench/gpu_setup.sh "${1:-.devcarry}"
steps=${2:-15000}
seconds=${3:-125}
data=/tmp/decoder_tune_data
run=/tmp/decoder_tune_run
step synth 150 python3 -m mlct.cli data synth --out "$data" --num "${NUM:-4000}" --seed 0 \
    --workers 16 --quiet
timeout "$seconds" python3 -m mlct.cli train ae --data "$data" --out "$run" \
    --init src/mlct/assets/model --device "${DEVICE:-cuda}" --quiet data.num_workers=8 \
    train.ae.cuda_graph=true ae.freeze_encoder=true ae.trajectory_weight=1.0 \
    ae.latent_noise=0.3 ae.hold_extension=0.5 train.ae.batch_size=128 train.ae.lr=1e-4 \
    "train.ae.max_steps=$steps" train.ae.log_every=500 train.ae.val_every=2500 \
    train.ae.ckpt_every=2500 > "$OUT/train.txt" 2>&1
echo "train: exit $?"
tail -n 2 "$OUT/train.txt"
mkdir -p "$final"
python3 - "$run/ae" "$final" <<'PY'
import json, sys
from pathlib import Path
from safetensors import safe_open
from safetensors.torch import load_file, save_file
stage, final = Path(sys.argv[1]), Path(sys.argv[2])
latest = stage / "checkpoints" / (stage / "checkpoints" / "latest").read_text().strip()
with safe_open(str(latest / "model.safetensors"), "pt") as handle:
    meta = handle.metadata()
tensors = load_file(str(latest / "model.safetensors"))
save_file({k: v.half() if v.is_floating_point() and not k.startswith("norm.") else v
           for k, v in tensors.items()}, str(final / "decoder_tune.safetensors"), metadata=meta)
(final / "decoder_tune_log.jsonl").write_text((stage / "log.jsonl").read_text())
rows = [json.loads(line) for line in (stage / "log.jsonl").read_text().splitlines()]
train = [r for r in rows if "samples_per_s" in r]
print(latest.name, "val", [(r["step"], round(r["val_loss"], 5)) for r in rows if "val_loss" in r])
if len(train) > 1:
    print(f"{(train[-1]['step'] - train[0]['step']) / (train[-1]['time'] - train[0]['time']):.0f} steps/s")
PY
ls -la "$final"
