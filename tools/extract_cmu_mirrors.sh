#!/usr/bin/env bash
# The commercially usable real set (docs/real_data.md "What is there") from git snapshots of the
# public repositories that redistribute CMU capture, imported and merged in one run:
#
#   bash tools/extract_cmu_mirrors.sh OUT CYUN PRZESTR MOTION_OUT EXPMAP [CMU131]
#
# CYUN .. EXPMAP are the git directories (bare clones or .git folders) of
# cyun9601/CMU-MOCAP-Data, Przestr/motion-capture, encadyma/motion-out and
# chaneyddtt/Convolutional-Sequence-to-Sequence-Model-for-Human-Dynamics; CMU131 a folder with
# 131_01..03.bvh. Files are read from each snapshot's HEAD; blobs a snapshot lacks are skipped.
# Makes OUT/raw/{cmu1,cmu2,expmap}, the imports OUT/{cmu1,cmu2,expmap} and their merge
# OUT/commercial (the real files stay in OUT, never in the repository). EXTRACT_ONLY=1 stops
# after OUT/raw.
set -euo pipefail
[ $# -ge 5 ] || { echo "usage: $0 OUT CYUN PRZESTR MOTION_OUT EXPMAP [CMU131]" >&2; exit 2; }
out=$1 cyun=$2 przestr=$3 motion_out=$4 expmap=$5 cmu131=${6:-}
raw=$out/raw
mkdir -p "$raw/cmu1" "$raw/cmu2" "$raw/expmap"

# copy GITDIR PATH DEST: one file of the snapshot, when its blob is there
copy() {
    if git --git-dir="$1" cat-file -e "HEAD:$2" 2>/dev/null; then
        mkdir -p "$(dirname "$3")"
        git --git-dir="$1" show "HEAD:$2" > "$3"
    else
        echo "absent from the snapshot: $2" >&2
    fi
}
files() { git --git-dir="$1" ls-tree -r --name-only HEAD -- "$2"; }

# cmu1: CMU's AMC of subjects 1-3, the BVH conversions, 131_01..03
for f in $(files "$cyun" data/CMU/asfamc/subjects/ | grep -E 'subjects/0[123]/'); do
    copy "$cyun" "$f" "$raw/cmu1/amc/${f#data/CMU/asfamc/subjects/}"
done
for f in $(files "$przestr" data/ | grep -i '\.bvh$'); do
    copy "$przestr" "$f" "$raw/cmu1/bvh/${f#data/}"
done
if [ -n "$cmu131" ]; then
    for t in 01 02 03; do cp "$cmu131/131_$t.bvh" "$raw/cmu1/"; done
fi

# cmu2: motion-out's assets, renamed there, named back to CMU's SS/SS_TT.amc and SS/SS.asf.
# Left out: md_walk (05_01), 131_01..03 (cmu1 has them), walk_03 and golf_01 (no CMU take named).
copy "$motion_out" assets/asf/moderndance.asf "$raw/cmu2/05/05.asf"
for t in 02 03 04 05 07; do
    copy "$motion_out" "assets/amc/moderndance/md_$t.amc" "$raw/cmu2/05/05_$t.amc"
done
copy "$motion_out" assets/asf/mjackson.asf "$raw/cmu2/131/131.asf"
for t in 04 05 06 07 08 09 10 11 12 13 14; do
    copy "$motion_out" "assets/amc/mjackson/131_$t.amc" "$raw/cmu2/131/131_$t.amc"
done
copy "$motion_out" assets/asf/martialwalk.asf "$raw/cmu2/135/135.asf"
for t in 02 03 04 05 06 07 08 09 10 11; do
    copy "$motion_out" "assets/amc/martialwalk/135_$t.amc" "$raw/cmu2/135/135_$t.amc"
done

# expmap: every sequence but the takes the cmu imports hold (CMU_TAKES)
skip=$(python -c "from mlct.data.corpora.cmu_expmap import CMU_TAKES; print(' '.join(CMU_TAKES))")
for f in $(files "$expmap" data/cmu_mocap/ | grep '\.txt$'); do
    rel=${f#data/cmu_mocap/}
    case " $skip " in *" ${rel%.txt} "*) continue ;; esac
    copy "$expmap" "$f" "$raw/expmap/$rel"
done

[ -z "${EXTRACT_ONLY:-}" ] || exit 0
# one import at a time: each uses both cores
mlct data import --corpus cmu "$raw/cmu1" --out "$out/cmu1"
mlct data import --corpus cmu "$raw/cmu2" --out "$out/cmu2"
mlct data import --corpus cmu-expmap "$raw/expmap" --out "$out/expmap"
for d in cmu1 cmu2 expmap; do mlct data check "$out/$d"; done
mlct data merge "$out/cmu1" "$out/cmu2" "$out/expmap" --out "$out/commercial"
