#!/usr/bin/env bash
# Cross-rig open-world protocol (issue 35): HDM05 templates and tuning from actors bd/bk/dg
# (train split); the other archives are other rigs that hold both foreign motions (no
# HDM05 class) and motions of HDM05 classes (scripts/crossrig_tables.py: the sets):
#   Bandai (BVH): set-1 foreign clips, set-2 foreign clips (five styles), set-1 and set-2
#     "run" clips (≈ jog), the set-1 kick (≈ kick) — with the background CMU 02 (its trials
#     of no HDM05 class; `cmu_all`, all ten trials, is issue 26's background);
#   CMU 02 (ASF/AMC): the foreign trials, trial 03 run/jog (≈ jog), trial 04 jump (≈ hop)
#     — with the background Bandai set 1 (its foreign clips).
# A background is never from the archive tested. Per configuration and side: one `tune`,
# annotations of every test set and of actor mm's composed documents (seeds) with every
# row (--min-confidence 0; the tuned minimum is applied by crossrig_tables.py measure),
# figures: share labelled (and labelled with the set's class), mm F1/F2/Acc/Edit/F1@50,
# confidence ECE/AUROC on mm rows and with the other rig's rows. The k-NN frame
# classifier with a "none" class trained on the same background (scripts/baseline_knn.py
# --none) is the peer, in the same run. Nothing is tuned on the documents reported on.
#
# The baseline, in the same run: the configurations named today* run mtanno as it was
# before issue 35 (a copy of the package at git revision BASE_REV, default b7ad3d8, made
# in OUT/base), the others the work tree's.
#
#   scripts/experiment_crossrig.sh [OUT] [SEEDS...]   (defaults: out/crossrig, seeds 1 2 3)
#   CONFIGS="today ..." the configurations (names below; default: those of docs/benchmarks.md,
#   "Cross-rig open world"; 13 tune runs, about 40 minutes on 2 cores); FEAT=DIR reuses
#   feature files (FEAT/hdm05, cmu02, bandai1, bandai2/<style>); PEER=0 skips the peer;
#   SIDES="bg_cmu" runs one side only; REUSE=1 keeps runs that have their figures.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${SHARED:-$here/../shared/data}
MTANNO=${MTANNO:-$here/.venv/bin/mtanno}
PY=${PY:-$here/.venv/bin/python}
OUT=${1:-$here/out/crossrig}
shift || true
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
SEEDS=${*:-1 2 3}
FEAT=${FEAT:-$OUT/feat}
CLIPS=$SHARED/hdm05_cut/clips.csv
[ -f "$CLIPS" ] || { echo "experiment_crossrig: $CLIPS not found" >&2; exit 2; }
CR=("$PY" "$here/scripts/crossrig_tables.py")
mkdir -p "$OUT" "$FEAT"
BASE_REV=${BASE_REV:-b7ad3d8}
if [ ! -f "$OUT/base/lib/mtanno/__init__.py" ]; then
  mkdir -p "$OUT/base/lib"
  git -C "$here" archive "$BASE_REV" mtanno | tar -x -C "$OUT/base/lib"
fi
BASE_MTANNO=("$PY" -P -c "import sys; sys.path.insert(0, '$OUT/base/lib'); \
from mtanno.__main__ import main; sys.argv[0] = 'mtanno'; main()")

feats() {  # SRC DEST: features with poses unless DEST has them already
  [ -n "$(ls "$2" 2>/dev/null)" ] || "$MTANNO" features "$1" -o "$2" --poses --jobs 2 -q
}
echo "== features with poses (cached in $FEAT)"
unpack() { "$PY" -c "import sys; sys.path.insert(0, '$here/tests'); import data_cache; \
print(data_cache.unpack_archive(data_cache.SHARED_DATA / 'bandai' / '$1.tar.xz'))"; }
feats "$SHARED/hdm05_cut" "$FEAT/hdm05"
feats "$SHARED/cmu_02" "$FEAT/cmu02"
[ -n "$(ls "$FEAT/bandai1" 2>/dev/null)" ] || feats "$(unpack set1)/data" "$FEAT/bandai1"
for s in active elderly feminine masculine normal; do
  [ -n "$(ls "$FEAT/bandai2/$s" 2>/dev/null)" ] || feats "$(unpack "set2-$s")/data" "$FEAT/bandai2/$s"
done
"${CR[@]}" sets "$FEAT" "$OUT/sets" | sed 's/^/   /'
S=$OUT/sets
[ -d "$OUT/mt" ] || "$MTANNO" learn-mt --manifest "$CLIPS" --features-dir "$FEAT/hdm05" \
  --split train -o "$OUT/mt" -q
MM=()
for seed in $SEEDS; do
  d=$OUT/seed$seed
  [ -f "$d/docs/truth.csv" ] || "$MTANNO" compose "$CLIPS" --actor mm --docs 10 --seed "$seed" \
    -o "$d/docs" 2>/dev/null
  feats "$d/docs" "$d/features"
  MM+=(--mm "$seed=$d/docs/truth.csv")
done

TRAIN=(--mt "$OUT/mt" --manifest "$CLIPS" --features-dir "$FEAT/hdm05" --split train --jobs 2)
declare -A TESTS=([bg_cmu]="b1_foreign b2_foreign b2_run b1_run b1_kick"
                  [bg_bandai]="cmu_foreign cmu_jog cmu_hop")
declare -A BGSET=([bg_cmu]=cmu_bg [bg_bandai]=b1_bg)

# configuration name → tune options (besides the training data and background);
# "relative": only the evidence that compares distances (no absolute verification cost)
RELATIVE="--evidence cost --evidence length --evidence margin --evidence background"
# "classifier": the default evidence and the frame classifier's agreement (issue 35, part 3)
ALL="$RELATIVE --evidence verify"
options() {
  case $1 in
    today|today_cmu_all) echo "" ;;
    retarget) echo "--invariance retarget" ;;
    mirror) echo "--invariance mirror" ;;
    retarget_mirror) echo "--invariance retarget --invariance mirror" ;;
    relative) echo "$RELATIVE" ;;
    relative_mirror) echo "$RELATIVE --invariance mirror" ;;
    relative_retarget) echo "$RELATIVE --invariance retarget" ;;
    classifier) echo "$ALL --evidence classifier" ;;
    relative_classifier) echo "$RELATIVE --evidence classifier" ;;
    classifier_mirror) echo "$ALL --evidence classifier --invariance mirror" ;;
    *) echo "experiment_crossrig: unknown configuration $1" >&2; return 2 ;;
  esac
}
CONFIGS=${CONFIGS:-today_cmu_all today relative retarget mirror classifier relative_classifier}

run() {  # NAME SIDE
  local name=$1 side=$2 r=$OUT/runs/$1/$2 bg=${BGSET[$2]} opts M=("$MTANNO")
  opts=$(options "$name")
  case $name in today*) M=("${BASE_MTANNO[@]}") ;; esac
  [ "$name" = today_cmu_all ] && { [ "$side" = bg_cmu ] || return 0; bg=cmu_all; }
  mkdir -p "$r"
  # shellcheck disable=SC2086
  /usr/bin/time -f "%e s %M KB" -o "$r/tune.time" "${M[@]}" tune "${TRAIN[@]}" \
    --background "$S/$bg" $opts -o "$r/tuned.toml" 2> "$r/tune.log"
  for t in ${TESTS[$side]}; do
    "${M[@]}" annotate --mt "$OUT/mt" --classes "$r/tuned.toml" "$S/$t" --min-confidence 0 \
      -o "$r/$t.csv" -q
  done
  for seed in $SEEDS; do
    "${M[@]}" annotate --mt "$OUT/mt" --classes "$r/tuned.toml" "$OUT/seed$seed/features" \
      --min-confidence 0 -o "$r/mm$seed.csv" -q
  done
  echo "-- $name, $side (background $bg; tune $(cat "$r/tune.time")):"
  "${CR[@]}" measure "$r" --sets "$S/sets.json" "${MM[@]}" | sed 's/^/   /'
  if [ "$name" = today ]; then  # every row kept: the tuned annotation of issue 10
    echo "   every row: $("${CR[@]}" measure "$r" --sets "$S/sets.json" "${MM[@]}" --min 0)"
  fi
}

for name in $CONFIGS; do
  for side in ${SIDES:-bg_cmu bg_bandai}; do
    if [ -n "${REUSE:-}" ] && [ -f "$OUT/runs/$name/$side/figures.json" ]; then continue; fi
    run "$name" "$side"
  done
done

if [ "${PEER:-1}" != 0 ]; then
  echo "== peer: k-NN frame classifier with a none class trained on the background"
  for side in bg_cmu bg_bandai; do
    r=$OUT/runs/peer_knn/$side
    mkdir -p "$r"
    for t in ${TESTS[$side]}; do
      [ -f "$r/$t.csv" ] || "$PY" "$here/scripts/baseline_knn.py" --manifest "$CLIPS" \
        --features-dir "$FEAT/hdm05" --split train --none "$S/${BGSET[$side]}" "$S/$t" \
        -o "$r/$t.csv" 2> /dev/null
    done
    for seed in $SEEDS; do
      [ -f "$r/mm$seed.csv" ] || "$PY" "$here/scripts/baseline_knn.py" --manifest "$CLIPS" \
        --features-dir "$FEAT/hdm05" --split train --none "$S/${BGSET[$side]}" \
        "$OUT/seed$seed/features" -o "$r/mm$seed.csv" 2> /dev/null
    done
    echo "-- peer, $side: $("${CR[@]}" measure "$r" --sets "$S/sets.json" "${MM[@]}")"
  done
fi

echo "== summary"
rows=()
for name in $CONFIGS; do [ "$name" = today ] && rows+=("today, min 0"); rows+=("$name"); done
"${CR[@]}" table "$OUT/runs" --rows peer_knn "${rows[@]}"
