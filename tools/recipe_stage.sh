# Sourced by the bundled-model recipes (tools/make_bundled_model*.sh); needs $work set.
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
# caption_sets [MOTIONS]: the benchmark and every caption set the bundle's stages train on, each
# made once into $work: synth (MOTIONS, default 4000), synth_rich (everyday captions),
# synth_focus (single claps, waves and turns listed 3x), synth_short (bare-verb captions),
# synth_coll (colloquial captions), synth_collturns (one-action turns and spins 3x more)
caption_sets() {
    local num="${1:-4000}"
    [ -f "$work/synth/synth.json" ] || mlct data synth --out "$work/synth" --num "$num" \
        --seed 0 --workers 2 --quiet
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
