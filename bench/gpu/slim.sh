#!/usr/bin/env bash
# bash bench/gpu/slim.sh on|off: keep the shipped files a GPU run does not need, or cannot carry
# whole, out of the device tool's transfer (its limit is 64 MiB; the tree holds ~128): `on`
# takes them out of git's index and ignores them (they stay on disk), `off` puts them back.
# Never commit between the two.
set -euo pipefail
cd "$(dirname "$0")/../.."
paths=(src/mlct/assets/minilm/model.safetensors src/mlct/assets/model/onnx
       src/mlct/assets/model/critic.safetensors src/mlct/assets/model/text_anchors.safetensors)
case "${1:?on|off}" in
    on)
        git rm -r -q --cached "${paths[@]}"
        for p in "${paths[@]}"; do echo "/$p"; done >> .git/info/exclude
        ;;
    off)
        git reset -q -- "${paths[@]}"
        for p in "${paths[@]}"; do sed -i "\|^/$p\$|d" .git/info/exclude; done
        ;;
    *) echo "usage: slim.sh on|off" >&2; exit 2 ;;
esac
git status --short | head
