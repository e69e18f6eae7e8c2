#!/usr/bin/env bash
# HDM05 annotation experiment (issue 3): templates from actors bd/bk/dg (train split) for
# the 11 classes, documents composed from actor mm (10 per seed), annotation without
# keyframes, P1/R1/F1 and P2/R2/F2 for the default (reference) Δ̄ and the paper's variant;
# then the retrieval table per class on one document of all actor-mm clips in manifest order.
#
#   scripts/experiment_hdm05.sh [OUT] [SEEDS...]      (defaults: out/hdm05, seeds 1 2 3)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
SHARED=${SHARED:-$here/../shared/data}
MTANNO=${MTANNO:-$here/.venv/bin/mtanno}
OUT=${1:-$here/out/hdm05}
shift || true
SEEDS=${*:-1 2 3}
CLIPS=$SHARED/hdm05_cut/clips.csv
[ -f "$CLIPS" ] || { echo "experiment_hdm05: $CLIPS not found" >&2; exit 2; }
mkdir -p "$OUT"

echo "== features of the 232 HDM05 clips"
"$MTANNO" features "$SHARED/hdm05_cut" -o "$OUT/features" --jobs 2 -q
echo "== templates (soft, reference procedure) from the train split (bd, bk, dg)"
"$MTANNO" learn-mt --manifest "$CLIPS" --features-dir "$OUT/features" --split train -o "$OUT/mt" -q

for seed in $SEEDS; do
  [ -f "$OUT/seed$seed/report_paper.json" ] && [ -n "${REUSE:-}" ] && continue
  d=$OUT/seed$seed
  echo "== seed $seed: 10 documents composed from actor mm"
  "$MTANNO" compose "$CLIPS" --actor mm --docs 10 --seed "$seed" -o "$d/docs" 2>/dev/null
  "$MTANNO" features "$d/docs" -o "$d/features" --jobs 2 -q
  for variant in reference paper; do
    "$MTANNO" annotate --mt "$OUT/mt" "$d/features" -o "$d/annotation_$variant.csv" \
      --variant "$variant" --jobs 2 -q
    echo "-- seed $seed, Δ̄ variant $variant"
    "$MTANNO" evaluate "$d/annotation_$variant.csv" --truth "$d/docs/truth.csv" \
      --json "$d/report_$variant.json" | tail -1
  done
done

echo "== summary (mean over seeds $SEEDS)"
"$here/.venv/bin/python" - "$OUT" $SEEDS <<'PY'
import json, sys
out, seeds = sys.argv[1], sys.argv[2:]
for variant in ("reference", "paper"):
    reps = [json.load(open(f"{out}/seed{s}/report_{variant}.json")) for s in seeds]
    mean = lambda lvl, k: sum(r[lvl][k] for r in reps) / len(reps)
    print(f"{variant:<10} P1 {mean('frame','P'):.3f} R1 {mean('frame','R'):.3f} "
          f"F1 {mean('frame','F'):.3f} | P2 {mean('segment','P'):.3f} "
          f"R2 {mean('segment','R'):.3f} F2 {mean('segment','F'):.3f}   "
          "(F1 per seed: " + ", ".join("%.3f" % r["frame"]["F"] for r in reps) + ")")
PY

echo "== retrieval table: one document of all 44 actor-mm clips (manifest order), delta 0.1"
r=$OUT/retrieval
"$MTANNO" compose "$CLIPS" --actor mm --docs 1 --in-order -o "$r/docs" 2>/dev/null
"$MTANNO" features "$r/docs" -o "$r/features" -q
"$MTANNO" evaluate-retrieval "$r/features" --mt "$OUT/mt" --truth "$r/docs/truth.csv" \
  --json "$r/retrieval.json"
