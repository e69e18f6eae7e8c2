#!/usr/bin/env bash
# Bandai set-2 annotation experiment (issue 10): another rig (BVH, 22 joints) and other
# classes (10 contents). Leave one style out, all five: templates per content from 12 clips
# per content of each of the four other styles (seeded draw, scripts/bandai_folds.py);
# every clip of the held-out style is annotated as one document and labelled with its
# content. Per fold: the k-NN frame-classifier baseline, the reference annotation, the
# annotation tuned by `mtanno tune` on the four training styles only (each held out in
# turn; held-out clips as separate documents, like the test), tuned + GA keyframes, the
# ablation and the unknown-class protocol. Prints the tables (means over the five styles).
#
#   scripts/experiment_bandai.sh [OUT] [STYLES...]   (defaults: out/bandai, all five styles)
#
# Environment: GA_RUNS (default 20 GA runs per content for the keyframes), REUSE=1 keeps
# tuned configurations and keyframes already there, UNKNOWN_STYLES (default: all held-out
# styles) the styles whose unknown-class protocol is run (ten tune runs per style).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
MTANNO=${MTANNO:-$here/.venv/bin/mtanno}
PY=$here/.venv/bin/python
OUT=${1:-$here/out/bandai}
shift || true
STYLES=${*:-active elderly feminine masculine normal}
UNKNOWN_STYLES=${UNKNOWN_STYLES:-$STYLES}
GA_RUNS=${GA_RUNS:-20}
TABLES=("$PY" "$here/scripts/annotation_tables.py")
ABLATION="without-tau without-reject without-refine without-resolve without-templates \
without-segments without-frames without-delta none"
mkdir -p "$OUT"

echo "== unpack the five set-2 archives (.cache/data) and compute their features"
for dir in $("$PY" "$here/scripts/bandai_folds.py" unpack); do
  style=$(basename "$(dirname "$dir")"); style=${style#set2-}
  "$MTANNO" features "$dir" -o "$OUT/features/$style" --jobs 2 -q
done
"$PY" "$here/scripts/bandai_folds.py" folds "$OUT/features" "$OUT/folds"

have() { [ -n "${REUSE:-}" ] && [ -e "$1" ]; }
for S in $STYLES; do
  f=$OUT/folds/$S
  echo "== held-out style $S: templates and tuning from the other four styles"
  "$MTANNO" learn-mt --manifest "$f/train.csv" --features-dir "$OUT/features" -o "$f/mt" -q
  "$PY" "$here/scripts/baseline_knn.py" --manifest "$f/train.csv" --features-dir \
    "$OUT/features" "$OUT/features/$S" -o "$f/annotation_knn.csv" 2> /dev/null
  "$MTANNO" annotate --mt "$f/mt" "$OUT/features/$S" -o "$f/annotation_reference.csv" -q
  have "$f/tuned.toml" || "$MTANNO" tune --mt "$f/mt" --manifest "$f/train.csv" \
    --features-dir "$OUT/features" --documents separate -o "$f/tuned.toml" \
    --ablation "$f/ablation" --jobs 2 2> "$f/tune.log"
  tail -1 "$f/tune.log"
  echo "   tuning inputs: $(grep -c '\.parquet$' "$f/tuned.toml") feature files, of style $S:" \
    "$(grep -c "_${S}_" "$f/tuned.toml" || true)"
  have "$f/kf_ga" || "$MTANNO" learn-keyframes --mt "$f/mt" --manifest "$f/train.csv" \
    --features-dir "$OUT/features" --runs "$GA_RUNS" -o "$f/kf_ga" --jobs 2 -q
  have "$f/tuned_kf.toml" || "$MTANNO" tune --mt "$f/mt" --keyframes "$f/kf_ga" \
    --manifest "$f/train.csv" --features-dir "$OUT/features" --documents separate \
    -o "$f/tuned_kf.toml" --jobs 2 -q
  "$MTANNO" annotate --mt "$f/mt" --classes "$f/tuned.toml" "$OUT/features/$S" \
    -o "$f/annotation_tuned.csv" -q
  "$MTANNO" annotate --mt "$f/mt" --classes "$f/tuned_kf.toml" --keyframes "$f/kf_ga" \
    "$OUT/features/$S" -o "$f/annotation_tuned_kf.csv" -q
  for a in $ABLATION; do
    "$MTANNO" annotate --mt "$f/mt" --classes "$f/ablation/$a.toml" "$OUT/features/$S" \
      -o "$f/annotation_ab_$a.csv" -q
  done
  for run in knn reference tuned tuned_kf $(for a in $ABLATION; do echo "ab_$a"; done); do
    "$MTANNO" evaluate "$f/annotation_$run.csv" --truth "$f/truth.csv" \
      --json "$f/report_$run.json" > "$f/report_$run.txt"
  done
  for run in knn reference tuned tuned_kf; do
    echo "-- $S, $run: $(tail -1 "$f/report_$run.txt")"
  done
  # unknown-class protocol: each content left out of templates, tuning and baseline; its
  # clips of the held-out style annotated
  case " $UNKNOWN_STYLES " in *" $S "*) ;; *) continue ;; esac
  for mt in "$f"/mt/*.json; do
    c=$(basename "$mt" .json)
    u=$f/unknown/$c
    mkdir -p "$u/mt"
    cp "$f"/mt/*.json "$u/mt/" && rm "$u/mt/$c.json"
    "${TABLES[@]}" drop "$f/train.csv" "$c" -o "$u/train.csv"
    docs=("$OUT/features/$S"/dataset-2_"${c}"_"${S}"_*.parquet)
    have "$u/tuned.toml" || "$MTANNO" tune --mt "$u/mt" --manifest "$u/train.csv" \
      --features-dir "$OUT/features" --documents separate -o "$u/tuned.toml" --jobs 2 -q
    "$MTANNO" annotate --mt "$u/mt" "${docs[@]}" -o "$u/reference.csv" -q
    "$MTANNO" annotate --mt "$u/mt" --classes "$u/tuned.toml" "${docs[@]}" -o "$u/tuned.csv" -q
    "$PY" "$here/scripts/baseline_knn.py" --manifest "$u/train.csv" --features-dir \
      "$OUT/features" "${docs[@]}" -o "$u/knn.csv" 2> /dev/null
    for run in reference tuned knn; do
      "${TABLES[@]}" unknown "$u/$run.csv" --truth "$f/truth.csv" --class "$c" -o "$u/$run.json"
    done
  done
done

echo "== summary (mean over the held-out styles: $STYLES)"
reports() { for s in $STYLES; do printf '%s,' "$OUT/folds/$s/report_$1.json"; done; }
"${TABLES[@]}" quality "baseline (k-NN, 1 s majority)=$(reports knn)" \
  "reference annotation=$(reports reference)" "tuned=$(reports tuned)" \
  "tuned + GA keyframes=$(reports tuned_kf)"
echo
echo "Ablation (tune re-run with one method left out; 'none' = one tau for all classes):"
"${TABLES[@]}" quality "tuned (all methods)=$(reports tuned)" \
  $(for a in $ABLATION; do echo "$a=$(reports "ab_$a")"; done)
echo
echo "Unknown-class rate (fraction of a left-out content's frames labelled with another):"
echo "(held-out styles of this protocol: $UNKNOWN_STYLES)"
rates() { for s in $UNKNOWN_STYLES; do ls "$OUT/folds/$s"/unknown/*/"$1".json; done | tr '\n' ','; }
"${TABLES[@]}" unknown-table "baseline=$(rates knn)" "reference=$(rates reference)" \
  "tuned=$(rates tuned)"
