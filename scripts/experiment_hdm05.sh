#!/usr/bin/env bash
# HDM05 annotation experiment (issues 3 and 7): templates from actors bd/bk/dg (train split)
# for the 11 classes, documents composed from actor mm (10 per seed). Annotation without
# keyframes (reference Δ̄ and the paper's variant), with the reference implementation's
# hand-made keyframes, and with keyframes learned from the train split by the genetic
# algorithm, the hard-template and the heuristic methods: P1/R1/F1, P2/R2/F2 and the time
# annotate spends annotating, side by side. Then the keyframe table per class (training
# fitness, mm clips found) and the retrieval table per class on one document of all
# actor-mm clips in manifest order.
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
echo "== keyframes: reference hand-made; learned from the train split (ga, hard, heuristic)"
"$here/.venv/bin/python" "$here/scripts/reference_keyframes.py" "$OUT/kf_reference"
for method in ga hard heuristic; do
  [ -d "$OUT/kf_$method" ] && [ -n "${REUSE:-}" ] && continue
  "$MTANNO" learn-keyframes --mt "$OUT/mt" --manifest "$CLIPS" --features-dir "$OUT/features" \
    --split train --method "$method" -o "$OUT/kf_$method" --jobs 2 -q
done

for seed in $SEEDS; do
  [ -f "$OUT/seed$seed/report_kf_heuristic.json" ] && [ -n "${REUSE:-}" ] && continue
  d=$OUT/seed$seed
  echo "== seed $seed: 10 documents composed from actor mm"
  "$MTANNO" compose "$CLIPS" --actor mm --docs 10 --seed "$seed" -o "$d/docs" 2>/dev/null
  "$MTANNO" features "$d/docs" -o "$d/features" --jobs 2 -q
  for run in reference paper kf_reference kf_ga kf_hard kf_heuristic; do
    case $run in
      reference|paper) extra=(--variant "$run") ;;
      *) extra=(--keyframes "$OUT/$run") ;;
    esac
    "$MTANNO" annotate --mt "$OUT/mt" "${extra[@]}" "$d/features" -o "$d/annotation_$run.csv" \
      2> "$d/annotate_$run.log"
    echo "-- seed $seed, $run ($(grep -o '[0-9.]* s of annotation' "$d/annotate_$run.log"))"
    "$MTANNO" evaluate "$d/annotation_$run.csv" --truth "$d/docs/truth.csv" \
      --json "$d/report_$run.json" | tail -1
  done
done

echo "== summary (mean over seeds $SEEDS)"
"$here/.venv/bin/python" - "$OUT" $SEEDS <<'PY'
import json, re, sys
out, seeds = sys.argv[1], sys.argv[2:]
names = {"reference": "no keyframes (reference Δ̄)", "paper": "no keyframes (paper Δ̄)",
         "kf_reference": "reference hand-made keyframes", "kf_ga": "GA keyframes",
         "kf_hard": "hard-template keyframes", "kf_heuristic": "heuristic keyframes"}
print("| annotation | P1 | R1 | F1 | P2 | R2 | F2 | seconds | F1 per seed | F2 per seed |")
print("|---|---|---|---|---|---|---|---|---|---|")
for run, name in names.items():
    reps = [json.load(open(f"{out}/seed{s}/report_{run}.json")) for s in seeds]
    secs = [float(re.search(r"([0-9.]+) s of annotation",
                            open(f"{out}/seed{s}/annotate_{run}.log").read()).group(1))
            for s in seeds]
    mean = lambda lvl, k: sum(r[lvl][k] for r in reps) / len(reps)
    print(f"| {name} | {mean('frame','P'):.3f} | {mean('frame','R'):.3f} | "
          f"{mean('frame','F'):.3f} | {mean('segment','P'):.3f} | {mean('segment','R'):.3f} | "
          f"{mean('segment','F'):.3f} | {sum(secs) / len(secs):.3f} | "
          + ", ".join("%.3f" % r["frame"]["F"] for r in reps) + " | "
          + ", ".join("%.3f" % r["segment"]["F"] for r in reps) + " |")
PY

echo "== keyframe queries per class: training fitness (train split) and actor mm's clips found"
"$here/.venv/bin/python" "$here/scripts/keyframes_table.py" --features "$OUT/features" \
  --manifest "$CLIPS" reference="$OUT/kf_reference" ga="$OUT/kf_ga" hard="$OUT/kf_hard" \
  heuristic="$OUT/kf_heuristic"

echo "== retrieval table: one document of all 44 actor-mm clips (manifest order), delta 0.1"
r=$OUT/retrieval
"$MTANNO" compose "$CLIPS" --actor mm --docs 1 --in-order -o "$r/docs" 2>/dev/null
"$MTANNO" features "$r/docs" -o "$r/features" -q
"$MTANNO" evaluate-retrieval "$r/features" --mt "$OUT/mt" --truth "$r/docs/truth.csv" \
  --json "$r/retrieval.json"
