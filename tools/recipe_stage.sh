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
