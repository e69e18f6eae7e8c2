#!/usr/bin/env bash
# The review loop on Bandai set 2 (issue 24): leave one style out; templates and tuning from
# the four other styles (12 clips per content each, as scripts/experiment_bandai.sh) plus K
# reviewed clips per content of the held-out style, K = 0, 1, 2. A reviewed clip is
# simulated from the held-out style's labels: `bandai_folds.py review` writes the truth CSV
# a person would download from the report page after accepting K clips per content
# (doc,start,end,label,fps), and adds its rows to the training manifest (actor = the
# held-out style, so `tune` holds the reviewed clips out as one more performer; learn-mt and
# tune take one source of examples, and the manifest is what gives tune the styles as
# performers). The reviewed clips are removed from the test documents. Per (style, K): the
# reference annotation and the tuned one, `mtanno evaluate --json`; then the tables
# (scripts/review_tables.py): per K the mean over the styles, and per style.
#
#   scripts/experiment_review.sh [OUT] [STYLES...]   (defaults: out/review, all five styles)
#
# Environment: FEATURES=DIR reuses feature files DIR/<style>/*.parquet (else they are
# computed from the unpacked archives, as experiment_bandai.sh does); KS (default "0 1 2");
# REUSE=1 keeps tuned configurations already there; JOBS (default 2).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
MTANNO=${MTANNO:-$here/.venv/bin/mtanno}
PY=$here/.venv/bin/python
OUT=${1:-$here/out/review}
shift || true
STYLES=${*:-active elderly feminine masculine normal}
KS=${KS:-0 1 2}
JOBS=${JOBS:-2}
mkdir -p "$OUT"
t0=$(date +%s)

if [ -n "${FEATURES:-}" ]; then
  feats=$FEATURES
else
  feats=$OUT/features
  echo "== unpack the five set-2 archives (.cache/data) and compute their features"
  for dir in $("$PY" "$here/scripts/bandai_folds.py" unpack); do
    style=$(basename "$(dirname "$dir")"); style=${style#set2-}
    "$MTANNO" features "$dir" -o "$feats/$style" --jobs "$JOBS" -q
  done
fi
"$PY" "$here/scripts/bandai_folds.py" folds "$feats" "$OUT/folds"

have() { [ -n "${REUSE:-}" ] && [ -e "$1" ]; }
for S in $STYLES; do
  for K in $KS; do
    d=$OUT/$S/k$K
    s0=$(date +%s)
    "$PY" "$here/scripts/bandai_folds.py" review "$OUT/folds/$S" "$d" --k "$K"
    mapfile -t docs < <(sed "s#^#$feats/#" "$d/documents.txt")
    "$MTANNO" learn-mt --manifest "$d/train.csv" --features-dir "$feats" -o "$d/mt" -q
    have "$d/tuned.toml" || "$MTANNO" tune --mt "$d/mt" --manifest "$d/train.csv" \
      --features-dir "$feats" --documents separate -o "$d/tuned.toml" --jobs "$JOBS" \
      2> "$d/tune.log"
    for run in reference tuned; do
      classes=()
      [ "$run" = tuned ] && classes=(--classes "$d/tuned.toml")
      "$MTANNO" annotate --mt "$d/mt" "${classes[@]}" "${docs[@]}" \
        -o "$d/annotation_$run.csv" -q --jobs "$JOBS"
      "$MTANNO" evaluate "$d/annotation_$run.csv" --truth "$d/truth.csv" \
        --json "$d/report_$run.json" > "$d/report_$run.txt"
    done
    echo "-- $S, K = $K ($(( $(date +%s) - s0 )) s): $(tail -1 "$d/report_tuned.txt")"
  done
done

echo "== review loop (Bandai set 2; styles: $STYLES; $(( $(date +%s) - t0 )) s)"
"$PY" "$here/scripts/review_tables.py" "$OUT" --styles $STYLES --ks $KS
