#!/usr/bin/env bash
# CMU mocap6 annotation experiment (issue 3): three long real recordings of one performer,
# every frame labelled with 12 exercise classes. For each rotation, templates are learned
# from the labelled segments of two documents and the third is annotated (no keyframes);
# P/R/F per rotation and over all three annotated documents together.
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
"$MTANNO" features "$SHARED/cmu_mocap6" --asf "$SHARED/cmu_02/02.asf" -o "$OUT/features" -q
"$MTANNO" truth mocap6 "$SHARED/cmu_mocap6/labels.json" -o "$OUT/truth.csv" 2>/dev/null

for test in $DOCS; do
  train=()
  for d in $DOCS; do [ "$d" = "$test" ] || train+=("$OUT/features/$d.parquet"); done
  r=$OUT/test_$test
  mkdir -p "$r"
  awk -F, -v t="$test" 'NR == 1 || $1 != t' "$OUT/truth.csv" > "$r/train_truth.csv"
  "$MTANNO" learn-mt --truth "$r/train_truth.csv" "${train[@]}" -o "$r/mt" -q
  "$MTANNO" annotate --mt "$r/mt" "$OUT/features/$test.parquet" -o "$r/annotation.csv" -q
  echo "-- annotate $test with templates from the other two"
  "$MTANNO" evaluate "$r/annotation.csv" --truth "$OUT/truth.csv" --json "$r/report.json"
done
echo "-- all three rotations together"
annotations=()
for test in $DOCS; do annotations+=("$OUT/test_$test/annotation.csv"); done
"$MTANNO" evaluate "${annotations[@]}" --truth "$OUT/truth.csv" --json "$OUT/report_all.json"
