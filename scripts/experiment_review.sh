#!/usr/bin/env bash
# The review loop on Bandai set 2 (issue 24, part 3): leave one style out; templates and
# tuning from the four other styles (12 clips per content each, the folds of
# scripts/experiment_bandai.sh) plus K reviewed clips per content of the held-out style S,
# K = 0, 1, 2. A reviewed clip is simulated from S's labels: `bandai_folds.py review` draws
# K clips per content of S (seeded, nested in K) and writes them as the truth CSV a person
# would download from the report page after accepting them (reviewed.csv:
# doc,start,end,label,fps; whole clips, 1-based inclusive, 30 Hz). The reviewed clips are
# removed from S's test documents and truth: a clip trained on is never tested on.
#
# How the reviewed truth reaches training. learn-mt and tune take one source of examples
# (--manifest and --truth exclude each other), so:
#   * learn-mt: --truth train_truth.csv FEATURE-FOLDERS — the fold's training clips as
#     whole-clip truth rows with reviewed.csv's rows appended as downloaded (the real loop:
#     downloaded truth → learn-mt --truth). The templates are those the fold's manifest
#     gives plus the reviewed clips (same examples, same order; checked on one fold: every
#     template equal but for the file paths it records).
#   * tune: --manifest train.csv — the fold's manifest plus one row per segment of
#     reviewed.csv read back by mtanno's truth reader, actor S (an extended manifest). tune
#     --truth would hold out each document in turn (some 500 folds, styles unknown to it);
#     the manifest's actor column is what makes tune hold out the styles, and the reviewed
#     clips as one more performer.
# Per (style, K): the reference annotation and the tuned one of the test documents,
# `mtanno evaluate --json`, and the tuned one once more on the test documents of the last K
# (the same documents for every K); then the tables (scripts/review_tables.py): per K the
# mean over the held-out styles, per style, and on the same documents.
#
#   scripts/experiment_review.sh [OUT] [STYLES...]   (defaults: out/review, all five styles)
#
# Environment: FEATURES=DIR reuses feature files DIR/<style>/*.parquet (else they are
# computed from the unpacked archives, as experiment_bandai.sh does); KS (default "0 1 2",
# in increasing order);
# SEED (default 0) of the reviewed draw; REUSE=1 keeps tuned configurations already there;
# JOBS (default 2). Every command runs under `nice` (the machine is shared).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
MTANNO=(nice "${MTANNO:-$here/.venv/bin/mtanno}")
PY=(nice "$here/.venv/bin/python")
OUT=${1:-$here/out/review}
shift || true
STYLES=${*:-active elderly feminine masculine normal}
KS=${KS:-0 1 2}
SEED=${SEED:-0}
JOBS=${JOBS:-2}
mkdir -p "$OUT"
t0=$(date +%s)

if [ -n "${FEATURES:-}" ]; then
  feats=$FEATURES
else
  feats=$OUT/features
  echo "== unpack the five set-2 archives (.cache/data) and compute their features"
  for dir in $("${PY[@]}" "$here/scripts/bandai_folds.py" unpack); do
    style=$(basename "$(dirname "$dir")"); style=${style#set2-}
    "${MTANNO[@]}" features "$dir" -o "$feats/$style" --jobs "$JOBS" -q
  done
fi
"${PY[@]}" "$here/scripts/bandai_folds.py" folds "$feats" "$OUT/folds"
folders=(); for s in active elderly feminine masculine normal; do folders+=("$feats/$s"); done

have() { [ -n "${REUSE:-}" ] && [ -e "$1" ]; }
for S in $STYLES; do
  for K in $KS; do
    d=$OUT/$S/k$K
    s0=$(date +%s)
    "${PY[@]}" "$here/scripts/bandai_folds.py" review "$OUT/folds/$S" "$d" --k "$K" \
      --seed "$SEED" --features "$feats"
    mapfile -t docs < <(sed "s#^#$feats/#" "$d/documents.txt")
    "${MTANNO[@]}" learn-mt --truth "$d/train_truth.csv" "${folders[@]}" -o "$d/mt" \
      > "$d/learn.log" 2>&1
    # learn-mt and tune must see the same examples: the truth table's rows and the
    # manifest's (header lines aside)
    n=$(grep -o 'from [0-9]* examples' "$d/learn.log" | grep -o '[0-9]*')
    [ "$n" -eq "$(( $(wc -l < "$d/train.csv") - 1 ))" ] || {
      echo "experiment_review: learn-mt learned from $n examples, train.csv lists" \
        "$(( $(wc -l < "$d/train.csv") - 1 ))" >&2; exit 1; }
    have "$d/tuned.toml" || "${MTANNO[@]}" tune --mt "$d/mt" --manifest "$d/train.csv" \
      --features-dir "$feats" --documents separate -o "$d/tuned.toml" --jobs "$JOBS" \
      2> "$d/tune.log"
    for run in reference tuned; do
      classes=()
      [ "$run" = tuned ] && classes=(--classes "$d/tuned.toml")
      "${MTANNO[@]}" annotate --mt "$d/mt" "${classes[@]}" "${docs[@]}" \
        -o "$d/annotation_$run.csv" -q --jobs "$JOBS"
      "${MTANNO[@]}" evaluate "$d/annotation_$run.csv" --truth "$d/truth.csv" \
        --json "$d/report_$run.json" > "$d/report_$run.txt"
    done
    echo "$(( $(date +%s) - s0 ))" > "$d/seconds.txt"
    echo "-- $S, K = $K: $n training examples, ${#docs[@]} test documents," \
      "$(cat "$d/seconds.txt") s; tuned: $(tail -1 "$d/report_tuned.txt")"
  done
  # every K also on the same test documents, those of the last K (the reviewed clips are
  # nested in K, so its test documents are among every smaller K's): report_tuned_common.json
  last=${KS##* }
  docargs=()
  while read -r doc; do doc=${doc##*/}; docargs+=(--doc "${doc%.parquet}"); done \
    < "$OUT/$S/k$last/documents.txt"
  for K in $KS; do
    "${MTANNO[@]}" evaluate "$OUT/$S/k$K/annotation_tuned.csv" --truth \
      "$OUT/$S/k$last/truth.csv" "${docargs[@]}" --json "$OUT/$S/k$K/report_tuned_common.json" \
      > /dev/null
  done
done

echo "== review loop (Bandai set 2; styles: $STYLES; $(( $(date +%s) - t0 )) s)"
# shellcheck disable=SC2086
"${PY[@]}" "$here/scripts/review_tables.py" "$OUT" --styles $STYLES --ks $KS
