#!/usr/bin/env bash
# The broad model with version 2 (tools/make_broad_model.sh, WITH_V2=1) on one GPU, in a time
# budget instead of fixed step counts:
#   bash tools/make_broad_model_gpu.sh WORK_DIR REAL_DATASET [REAL_DATASET ...]
# The data is made there (benchmark version 4, 6,000 motions, and version 2, 4,000, with the
# bundle's caption sets of each: recipe_stage.sh) and merged with the real datasets (for a
# bundle, only corpora whose license allows commercial use). Then, from the bundled model:
# - the autoencoder, every weight free, on the merged set (not on the procedural set first: the
#   CPU recipe's later third round on the merged set is what kept version 2 and the real set),
#   eager (ae.hold_extension is refused in a captured step) with LOADER_WORKERS (6) batch
#   makers, bf16 autocast, batch AE_BATCH (128), lr AE_LR (5e-4, the CPU recipe's second
#   round's);
# - stage 2 on its latents of the same set, replayed from a CUDA graph, float32 (bf16 stage 2
#   diverged on a GPU: docs/training.md), batch CM_BATCH (128), lr 2e-4;
# - the export (--half). The durations, the critic and the text anchors are left to a CPU
#   (minutes), on the same data made there by the same commands:
#   mlct train durations --data WORK/synth --model WORK/model
#   mlct train critic --data WORK/synth_rich --model WORK/model --samples 8
#   mlct train anchors --data WORK/mixed --model WORK/model
# Each training's steps come from its rate in a short calibration run, so that the two share
# BUDGET_S seconds (default 420; AE_SHARE of them the autoencoder's, default 0.5), or what is
# left until END_AT (epoch seconds); a training that overruns its share by a minute, or would
# pass END_AT, is stopped and exported from its last checkpoint.
# DEVICE (cuda), WORKERS (16 synth processes), MOTIONS and V2_MOTIONS (6,000 and 4,000) can be
# set for a dry run on a CPU.
set -euo pipefail
work="${1:?WORK_DIR}"
shift
[ "$#" -ge 1 ] || { echo "give one or more imported real datasets" >&2; exit 2; }
source "$(dirname "$0")/recipe_stage.sh"
export WORKERS="${WORKERS:-16}"
device="${DEVICE:-cuda}"
stamp data
(BENCHMARK_VERSION=4; caption_sets "${MOTIONS:-6000}") &
v4=$!
(work="$work/v2"; BENCHMARK_VERSION=2; caption_sets "${V2_MOTIONS:-4000}") &
wait "$v4" && wait $!
[ -f "$work/mixed/provenance.jsonl" ] || mlct data merge "$work/synth_collturns" \
    "$work/v2/synth_collturns" "$@" --out "$work/mixed"
ae_args=(--init bundled ae.freeze_encoder=false train.ae.precision=bf16
         "train.ae.batch_size=${AE_BATCH:-128}" "train.ae.lr=${AE_LR:-5e-4}"
         "data.num_workers=${LOADER_WORKERS:-6}")
cm_args=(--init bundled text.encoder=minilm+sides denoiser.dropout=0.0 train.cm.lr=2e-4
         train.cm.seed=31 train.cm.precision=fp32 "train.cm.batch_size=${CM_BATCH:-128}")
graph=$([ "$device" = cuda ] && echo true || echo false)
command_of() {  # stage, out, steps, extra...: CMD, one training of STEPS logged 20 times
    local name=$1 out=$2 steps=$3; shift 3
    local every=$(( steps / 20 > 0 ? steps / 20 : 1 )) quarter=$(( steps / 4 > 0 ? steps / 4 : 1 ))
    CMD=(mlct train "$name" --data "$work/mixed" --out "$out" --device "$device" --quiet "$@"
         "train.$name.max_steps=$steps" "train.$name.log_every=$every"
         "train.$name.val_every=$quarter" "train.$name.ckpt_every=$quarter")
}
train() { command_of "$@"; "${CMD[@]}"; }
rate() {  # steps per second of a run's stage, between its second and last log lines
    python3 - "$1/$2/log.jsonl" <<'PY'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if '"samples_per_s"' in l]
a, b = rows[1], rows[-1]
print(f"{(b['step'] - a['step']) / (b['time'] - a['time']):.3f}")
PY
}
stamp calibration
rm -rf "$work/calibration"
train ae "$work/calibration" "${CAL_AE_STEPS:-200}" "${ae_args[@]}"
ae_rate=$(rate "$work/calibration" ae)
if ! train cm "$work/calibration" "${CAL_CM_STEPS:-400}" "${cm_args[@]}" \
        "train.cm.cuda_graph=$graph" > "$work/calibration_cm.txt" 2>&1; then
    cat "$work/calibration_cm.txt"
    echo "stage 2 replayed from a CUDA graph failed; eager steps instead" >&2
    graph=false
    rm -rf "$work/calibration/cm"
    train cm "$work/calibration" "${CAL_CM_STEPS:-400}" "${cm_args[@]}" train.cm.cuda_graph=false
fi
cm_rate=$(rate "$work/calibration" cm)
# END_AT (epoch seconds): the budget is what is left until then, less the two start-ups and
# the export
budget="${BUDGET_S:-420}"
[ -n "${END_AT:-}" ] && budget=$(( END_AT - $(date +%s) - 70 ))
read -r ae_steps cm_steps < <(python3 -c "
b, s = $budget, ${AE_SHARE:-0.5}
print(max(100, int($ae_rate * b * s) // 100 * 100), max(100, int($cm_rate * b * (1 - s)) // 100 * 100))")
stamp "autoencoder: $ae_rate steps/s, $ae_steps steps; stage 2 ($graph graph): $cm_rate steps/s, $cm_steps steps"
limit() {  # steps, rate: a minute more than it should take, and never past END_AT less 30 s
    python3 -c "import time; e = ${END_AT:-0}; l = $1 / $2 + 60
print(max(1, int(min(l, e - time.time() - 30) if e else l)))"
}
stamp autoencoder
command_of ae "$work/run" "$ae_steps" "${ae_args[@]}"
timeout "$(limit "$ae_steps" "$ae_rate")" "${CMD[@]}" || echo "autoencoder stopped: exit $?" >&2
stamp stage 2
command_of cm "$work/run" "$cm_steps" "${cm_args[@]}" "train.cm.cuda_graph=$graph"
timeout "$(limit "$cm_steps" "$cm_rate")" "${CMD[@]}" || echo "stage 2 stopped: exit $?" >&2
stamp export
rm -rf "$work/model"
mlct export "$work/run" --out "$work/model" --half
record_training_data "$work/model" "$work/mixed" "{\"script\": \"tools/make_broad_model_gpu.sh\",
    \"from\": \"bundled\", \"benchmark_version\": 4, \"with_version_2\": true,
    \"autoencoder_steps\": $ae_steps, \"stage_2_steps\": $cm_steps}"
stamp done
echo "$work/model"
