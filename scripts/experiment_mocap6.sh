#!/usr/bin/env bash
# CMU mocap6 annotation experiment (issues 3, 7 and 10): three long real recordings of one
# performer, every frame labelled with 12 exercise classes. For each rotation, templates
# and keyframe queries (ga, hard, heuristic) are learned from the labelled segments of two
# documents and the third is annotated, without keyframes and with each kind; P/R/F over
# all three annotated documents together, side by side. Issue 10: the k-NN baseline, the
# annotation tuned by `mtanno tune` on the two training documents (each held out in turn),
# with and without GA keyframes, the ablation and the unknown-class protocol.
#
#   scripts/experiment_mocap6.sh [OUT]      (default: out/mocap6)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${SHARED:-$here/../shared/data}
MTANNO=${MTANNO:-$here/.venv/bin/mtanno}
OUT=${1:-$here/out/mocap6}
DOCS="13_29 13_30 13_31"
[ -d "$SHARED/cmu_mocap6" ] || { echo "experiment_mocap6: $SHARED/cmu_mocap6 not found" >&2; exit 2; }
mkdir -p "$OUT"

# The mocap6 AMC files name an ASF that was never published: subject 02's has the same bones.
"$MTANNO" features "$SHARED/cmu_mocap6" --asf "$SHARED/cmu_02/02.asf" -o "$OUT/features" --poses -q
"$MTANNO" truth mocap6 "$SHARED/cmu_mocap6/labels.json" -o "$OUT/truth.csv" 2>/dev/null

RUNS="none ga hard heuristic"
for test in $DOCS; do
  train=()
  for d in $DOCS; do [ "$d" = "$test" ] || train+=("$OUT/features/$d.parquet"); done
  r=$OUT/test_$test
  mkdir -p "$r"
  awk -F, -v t="$test" 'NR == 1 || $1 != t' "$OUT/truth.csv" > "$r/train_truth.csv"
  "$MTANNO" learn-mt --truth "$r/train_truth.csv" "${train[@]}" -o "$r/mt" -q
  for run in $RUNS; do
    extra=()
    if [ "$run" != none ]; then
      "$MTANNO" learn-keyframes --mt "$r/mt" --truth "$r/train_truth.csv" "${train[@]}" \
        --method "$run" -o "$r/kf_$run" --jobs 2 -q
      extra=(--keyframes "$r/kf_$run")
    fi
    "$MTANNO" annotate --mt "$r/mt" "${extra[@]}" "$OUT/features/$test.parquet" \
      -o "$r/annotation_$run.csv" 2> "$r/annotate_$run.log"
  done
  echo "-- annotate $test with templates from the other two (no keyframes)"
  "$MTANNO" evaluate "$r/annotation_none.csv" --truth "$OUT/truth.csv" --json "$r/report.json"
done
echo "-- all three rotations together"
for run in $RUNS; do
  annotations=()
  for test in $DOCS; do annotations+=("$OUT/test_$test/annotation_$run.csv"); done
  "$MTANNO" evaluate "${annotations[@]}" --truth "$OUT/truth.csv" --json "$OUT/report_$run.json" \
    > "$OUT/report_$run.txt"
done
cp "$OUT/report_none.json" "$OUT/report_all.json"
cat "$OUT/report_none.txt"
"$here/.venv/bin/python" - "$OUT" $DOCS <<'PY'
import json, re, sys
out, docs = sys.argv[1], sys.argv[2:]
names = {"none": "no keyframes", "ga": "GA keyframes", "hard": "hard-template keyframes",
         "heuristic": "heuristic keyframes"}
print("| annotation (all three rotations) | P1 | R1 | F1 | P2 | R2 | F2 | Edit | F1@50 | seconds |")
print("|---|---|---|---|---|---|---|---|---|---|")
field = lambda r, key: "–" if r.get(key) is None else "%.3f" % r[key]
for run, name in names.items():
    r = json.load(open(f"{out}/report_{run}.json"))
    secs = sum(float(re.search(r"([0-9.]+) s of annotation",
                               open(f"{out}/test_{d}/annotate_{run}.log").read()).group(1))
               for d in docs)
    f, g = r["frame"], r["segment"]
    print(f"| {name} | {f['P']:.3f} | {f['R']:.3f} | {f['F']:.3f} | {g['P']:.3f} | "
          f"{g['R']:.3f} | {g['F']:.3f} | {field(r, 'edit')} | {field(r, 'f1_50')} | {secs:.3f} |")
PY

# --------------------------------------------------------------------------- issue 10
echo "== issue 10: baseline, tuned (tuning on the two training documents only), ablation"
TABLES=("$here/.venv/bin/python" "$here/scripts/annotation_tables.py")
ABLATION="without-tau without-reject without-refine without-resolve without-templates \
without-segments without-frames without-delta none"
for test in $DOCS; do
  train=()
  for d in $DOCS; do [ "$d" = "$test" ] || train+=("$OUT/features/$d.parquet"); done
  r=$OUT/test_$test
  "$MTANNO" tune --mt "$r/mt" --truth "$r/train_truth.csv" "${train[@]}" -o "$r/tuned.toml" \
    --ablation "$r/ablation" -q
  echo "   $test: tuned on $(grep -c '\.parquet$' "$r/tuned.toml") feature files, $test among" \
    "them: $(grep -c "/$test.parquet" "$r/tuned.toml")"
  "$MTANNO" tune --mt "$r/mt" --keyframes "$r/kf_ga" --truth "$r/train_truth.csv" "${train[@]}" \
    -o "$r/tuned_kf.toml" -q
  "$here/.venv/bin/python" "$here/scripts/baseline_knn.py" --truth "$r/train_truth.csv" \
    $(printf -- '--train %s ' "${train[@]}") "$OUT/features/$test.parquet" \
    -o "$r/annotation_knn.csv" 2> /dev/null
  "$MTANNO" annotate --mt "$r/mt" --classes "$r/tuned.toml" "$OUT/features/$test.parquet" \
    -o "$r/annotation_tuned.csv" -q
  # issue 26: the same tuning without the confidence (every row kept, as in issue 10)
  "$MTANNO" annotate --mt "$r/mt" --classes "$r/tuned.toml" "$OUT/features/$test.parquet" \
    --min-confidence 0 -o "$r/annotation_tuned_all.csv" -q
  "$MTANNO" annotate --mt "$r/mt" --classes "$r/tuned_kf.toml" --keyframes "$r/kf_ga" \
    "$OUT/features/$test.parquet" -o "$r/annotation_tuned_kf.csv" -q
  for a in $ABLATION; do
    "$MTANNO" annotate --mt "$r/mt" --classes "$r/ablation/$a.toml" \
      "$OUT/features/$test.parquet" -o "$r/annotation_ab_$a.csv" -q
  done
  # unknown-class protocol: each class of the test document that the training documents
  # also hold, left out of templates, tuning and baseline
  for c in $(awk -F, -v t="$test" 'NR > 1 && $1 == t {print $4}' "$OUT/truth.csv" | sort -u); do
    grep -q ",$c," "$r/train_truth.csv" || continue
    u=$r/unknown/$c
    mkdir -p "$u/mt"
    cp "$r"/mt/*.json "$u/mt/" && rm "$u/mt/$c.json"
    "${TABLES[@]}" drop "$r/train_truth.csv" "$c" -o "$u/train_truth.csv"
    "$MTANNO" annotate --mt "$u/mt" "$OUT/features/$test.parquet" -o "$u/reference.csv" -q
    "$MTANNO" tune --mt "$u/mt" --truth "$u/train_truth.csv" "${train[@]}" -o "$u/tuned.toml" -q
    "$MTANNO" annotate --mt "$u/mt" --classes "$u/tuned.toml" "$OUT/features/$test.parquet" \
      -o "$u/tuned.csv" -q
    "$MTANNO" annotate --mt "$u/mt" --classes "$u/tuned.toml" "$OUT/features/$test.parquet" \
      --min-confidence 0 -o "$u/tuned_all.csv" -q
    "$here/.venv/bin/python" "$here/scripts/baseline_knn.py" --truth "$u/train_truth.csv" \
      $(printf -- '--train %s ' "${train[@]}") "$OUT/features/$test.parquet" -o "$u/knn.csv" \
      2> /dev/null
    for run in reference tuned tuned_all knn; do
      "${TABLES[@]}" unknown "$u/$run.csv" --truth "$OUT/truth.csv" --class "$c" -o "$u/$run.json"
    done
  done
done
for run in knn tuned tuned_all tuned_kf $(for a in $ABLATION; do echo "ab_$a"; done); do
  annotations=()
  for test in $DOCS; do annotations+=("$OUT/test_$test/annotation_$run.csv"); done
  "$MTANNO" evaluate "${annotations[@]}" --truth "$OUT/truth.csv" --json "$OUT/report_$run.json" \
    > "$OUT/report_$run.txt"
done
echo "== issue 10 summary (all three rotations evaluated together)"
"${TABLES[@]}" quality "baseline (k-NN, 1 s majority)=$OUT/report_knn.json" \
  "reference annotation=$OUT/report_none.json" "tuned=$OUT/report_tuned.json" \
  "tuned, every row (--min-confidence 0)=$OUT/report_tuned_all.json" \
  "tuned + GA keyframes=$OUT/report_tuned_kf.json"
echo
echo "Ablation (tune re-run with one method left out; 'none' = one tau for all classes):"
"${TABLES[@]}" quality "tuned (all methods)=$OUT/report_tuned.json" \
  $(for a in $ABLATION; do echo "$a=$OUT/report_ab_$a.json"; done)
echo
echo "Unknown-class rate (fraction of a left-out class's frames labelled with another class):"
rates() { ls "$OUT"/test_*/unknown/*/"$1".json | tr '\n' ','; }
"${TABLES[@]}" unknown-table "baseline=$(rates knn)" "reference=$(rates reference)" \
  "tuned=$(rates tuned)" "tuned, every row (--min-confidence 0)=$(rates tuned_all)"
