# Sourced by the bundled-model recipe (tools/make_bundled_model_3h.sh and
# make_bundled_model_narrow_decoder.sh); needs $work set.
# stage RUN NAME ARGS...: train stage NAME into $work/RUN, or resume it when it already has
# checkpoints (each recipe is resumable). DATA=DIR stage ...: another dataset than $work/synth;
# AE=RUN stage ...: stage 2 on that autoencoder, passed again when resumed.
stage() {
    local run="$1" name="$2"; shift 2
    local data="${DATA:-$work/synth}"
    local ae=()
    [ -n "${AE:-}" ] && ae=(--ae "$AE")
    if ls "$work/$run/$name/checkpoints"/step-* >/dev/null 2>&1; then
        mlct train "$name" --data "$data" --out "$work/$run" "${ae[@]}" --resume
    else
        mlct train "$name" --data "$data" --out "$work/$run" "${ae[@]}" "$@"
    fi
}
stamp() { echo "[$(date -u +%H:%M:%S)] $*"; }
# caption_sets [MOTIONS]: the benchmark (BENCHMARK_VERSION, default 2) and every caption set
# the bundle's stages train on, each made once into $work: synth (MOTIONS, default 4000),
# synth_rich (everyday captions), synth_focus (single claps, waves and turns listed 3x),
# synth_short (bare-verb captions), synth_coll (colloquial captions), synth_collturns
# (one-action turns and spins 3x more); WORKERS (default 2): the synth processes
caption_sets() {
    local num="${1:-4000}"
    [ -f "$work/synth/synth.json" ] || mlct data synth --out "$work/synth" --num "$num" \
        --seed 0 --workers "${WORKERS:-2}" --quiet --benchmark-version "${BENCHMARK_VERSION:-2}"  # 2: 21 families
    [ -f "$work/synth_rich/synth.json" ] || mlct data rephrase "$work/synth" \
        --out "$work/synth_rich"
    [ -f "$work/synth_focus/synth.json" ] || mlct data oversample "$work/synth_rich" \
        --out "$work/synth_focus" --families clap,wave,turn --times 3
    [ -f "$work/synth_short/synth.json" ] || mlct data rephrase "$work/synth_focus" \
        --out "$work/synth_short" --vocabulary short --per-motion 2
    [ -f "$work/synth_coll/synth.json" ] || mlct data rephrase "$work/synth_short" \
        --out "$work/synth_coll" --vocabulary colloquial --per-motion 3 --seed 1
    [ -f "$work/synth_collturns/synth.json" ] || mlct data oversample "$work/synth_coll" \
        --out "$work/synth_collturns" --families turn,spin --times 3
}
# The one-pass recipe's stage 2 (tools/make_bundled_model_3h.sh), given $work/noise and
# $work/armdec.
# stage2_on_body SEED: on the body's 3 tokens, from step 0 on every caption set. DENOISER: the
# denoiser's size as config overrides, by default version 6's 3 x 192.
VERSION_6_DENOISER="denoiser.width=192 denoiser.ff_dim=768 denoiser.layers=3"
stage2_on_body() {
    # shellcheck disable=SC2086  # DENOISER is a list of overrides, split on purpose
    DATA="$work/synth_collturns" AE="$work/noise" stage cm cm --config small \
        ${DENOISER:-$VERSION_6_DENOISER} text.encoder=minilm+sides denoiser.dropout=0.0 \
        "train.cm.max_steps=${CM_STEPS:-28000}" train.cm.lr=4e-4 \
        "train.cm.seed=$1" train.cm.precision=bf16
}
# stage2_on_all SEED: grown onto all 6 tokens, exported with the arm pair's decoder, then the
# durations, the critic and the text anchors; $work/model
stage2_on_all() {
    local seed="$1"
    # float32, so that the grown stage 2 does not start from weights rounded to float16
    [ -f "$work/model_cm/config.json" ] || mlct export "$work/cm" --out "$work/model_cm"
    stamp stage 2 on 6 tokens
    AE="$work/armdec" DATA="$work/synth_collturns" stage cm6 cm --init "$work/model_cm" \
        text.encoder=minilm+sides denoiser.dropout=0.0 "train.cm.max_steps=${CM6_STEPS:-10000}" \
        train.cm.lr=2e-4 "train.cm.seed=$((seed + 31))" train.cm.precision=bf16
    if [ ! -f "$work/model/text_anchors.safetensors" ]; then
        rm -rf "$work/model"
        mlct export "$work/cm6" --out "$work/model" --half --decoder-from "$work/armdec"
        stamp durations, critic, text anchors
        mlct train durations --data "$work/synth" --model "$work/model"
        mlct train critic --data "$work/synth_rich" --model "$work/model" --samples 8
        mlct train anchors --data "$work/synth_collturns" --model "$work/model"
    fi
}
# record_training_data MODEL_DIR MIXED RECIPE_JSON: write into the model's config.json its
# training data (each corpus of MIXED, its motions and license: data/corpora.py) and its recipe
record_training_data() {
    python3 - "$1/config.json" "$2" "$3" <<'PY'
import json, sys
from mlct.data.corpora import training_data
path, mixed, recipe = sys.argv[1:]
config = json.load(open(path))
config["training_data"] = training_data(mixed)
config["recipe"] = json.loads(recipe)
json.dump(config, open(path, "w"), indent=2)
PY
}
