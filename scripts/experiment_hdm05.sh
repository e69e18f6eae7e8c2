#!/usr/bin/env bash
# HDM05 annotation experiment (issues 3, 7 and 10): templates from actors bd/bk/dg (train split)
# for the 11 classes, documents composed from actor mm (10 per seed). Annotation without
# keyframes (reference Δ̄ and the paper's variant), with the reference implementation's
# hand-made keyframes, and with keyframes learned from the train split by the genetic
# algorithm, the hard-template and the heuristic methods: P1/R1/F1, P2/R2/F2 and the time
# annotate spends annotating, side by side. Then the keyframe table per class (training
# fitness, mm clips found) and the retrieval table per class on one document of all
# actor-mm clips in manifest order. Issue 10: the k-NN frame-classifier baseline, the
# annotation tuned by `mtanno tune` on the train split only (with and without GA keyframes),
# the ablation (tune with each method left out) and the unknown-class protocol (each class
# in turn left out of templates and tuning, the fraction of its frames labelled anyway). Issue
# 26: the open-world protocol (scripts/experiment_openworld.sh) into OUT/openworld.
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
      reference|paper) extra=(--dbar "$run") ;;
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
print("| annotation | P1 | R1 | F1 | P2 | R2 | F2 | Edit | F1@50 | seconds | F1 per seed | F2 per seed |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
field = lambda reps, key: ("–" if any(r.get(key) is None for r in reps)
                           else "%.3f" % (sum(r[key] for r in reps) / len(reps)))
for run, name in names.items():
    reps = [json.load(open(f"{out}/seed{s}/report_{run}.json")) for s in seeds]
    secs = [float(re.search(r"([0-9.]+) s of annotation",
                            open(f"{out}/seed{s}/annotate_{run}.log").read()).group(1))
            for s in seeds]
    mean = lambda lvl, k: sum(r[lvl][k] for r in reps) / len(reps)
    print(f"| {name} | {mean('frame','P'):.3f} | {mean('frame','R'):.3f} | "
          f"{mean('frame','F'):.3f} | {mean('segment','P'):.3f} | {mean('segment','R'):.3f} | "
          f"{mean('segment','F'):.3f} | {field(reps, 'edit')} | {field(reps, 'f1_50')} | "
          f"{sum(secs) / len(secs):.3f} | "
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

# --------------------------------------------------------------------------- issue 10
echo "== issue 10: tune on the train split only (bd, bk, dg; the config lists its inputs)"
T=$OUT/tune
mkdir -p "$T"
if [ ! -f "$T/tuned.toml" ] || [ -z "${REUSE:-}" ]; then
  "$MTANNO" tune --mt "$OUT/mt" --manifest "$CLIPS" --features-dir "$OUT/features" \
    --split train -o "$T/tuned.toml" --ablation "$T/ablation" --jobs 2 2> "$T/tune.log"
  "$MTANNO" tune --mt "$OUT/mt" --keyframes "$OUT/kf_ga" --manifest "$CLIPS" \
    --features-dir "$OUT/features" --split train -o "$T/tuned_kf.toml" --jobs 2 -q
fi
tail -1 "$T/tune.log"
echo "   tuning inputs: $(grep -c '\.parquet$' "$T/tuned.toml") feature files," \
  "of actor mm: $(grep -c '/HDM_mm_' "$T/tuned.toml")"
ABLATION="without-tau without-reject without-refine without-resolve without-templates \
without-segments without-frames without-delta none"
for seed in $SEEDS; do
  d=$OUT/seed$seed
  python_knn=("$here/.venv/bin/python" "$here/scripts/baseline_knn.py")
  "${python_knn[@]}" --manifest "$CLIPS" --features-dir "$OUT/features" --split train \
    "$d/features" -o "$d/annotation_knn.csv" 2> "$d/annotate_knn.log"
  "$MTANNO" annotate --mt "$OUT/mt" --classes "$T/tuned.toml" "$d/features" \
    -o "$d/annotation_tuned.csv" 2> "$d/annotate_tuned.log"
  "$MTANNO" annotate --mt "$OUT/mt" --classes "$T/tuned_kf.toml" --keyframes "$OUT/kf_ga" \
    "$d/features" -o "$d/annotation_tuned_kf.csv" 2> "$d/annotate_tuned_kf.log"
  for a in $ABLATION; do
    "$MTANNO" annotate --mt "$OUT/mt" --classes "$T/ablation/$a.toml" "$d/features" \
      -o "$d/annotation_ab_$a.csv" -q
  done
  for run in knn tuned tuned_kf $(for a in $ABLATION; do echo "ab_$a"; done); do
    "$MTANNO" evaluate "$d/annotation_$run.csv" --truth "$d/docs/truth.csv" \
      --json "$d/report_$run.json" > "$d/report_$run.txt"
  done
  echo "-- seed $seed: baseline $(tail -1 "$d/report_knn.txt")"
  echo "-- seed $seed: tuned    $(tail -1 "$d/report_tuned.txt")"
done

echo "== unknown-class protocol: each class left out of templates, tuning and baseline"
U=$OUT/unknown
TABLES=("$here/.venv/bin/python" "$here/scripts/annotation_tables.py")
for mt in "$OUT"/mt/*.json; do
  c=$(basename "$mt" .json)
  u=$U/$c
  mkdir -p "$u/mt"
  cp "$OUT"/mt/*.json "$u/mt/" && rm "$u/mt/$c.json"
  "${TABLES[@]}" drop "$CLIPS" "$c" -o "$u/clips.csv"
  [ -f "$u/tuned.toml" ] && [ -n "${REUSE:-}" ] || \
    "$MTANNO" tune --mt "$u/mt" --manifest "$u/clips.csv" --features-dir "$OUT/features" \
      --split train -o "$u/tuned.toml" --jobs 2 -q
  for seed in $SEEDS; do
    d=$OUT/seed$seed
    "$MTANNO" annotate --mt "$u/mt" "$d/features" -o "$u/seed${seed}_reference.csv" -q
    "$MTANNO" annotate --mt "$u/mt" --classes "$u/tuned.toml" "$d/features" \
      -o "$u/seed${seed}_tuned.csv" -q
    "$here/.venv/bin/python" "$here/scripts/baseline_knn.py" --manifest "$u/clips.csv" \
      --features-dir "$OUT/features" --split train "$d/features" -o "$u/seed${seed}_knn.csv" \
      2> /dev/null
    for run in reference tuned knn; do
      "${TABLES[@]}" unknown "$u/seed${seed}_$run.csv" --truth "$d/docs/truth.csv" --class "$c" \
        -o "$u/seed${seed}_$run.json"
    done
  done
done

echo "== issue 10 summary (mean over seeds $SEEDS; tuning and templates from bd, bk, dg only)"
reports() { for s in $SEEDS; do printf '%s,' "$OUT/seed$s/report_$1.json"; done; }
"${TABLES[@]}" quality "baseline (k-NN, 1 s majority)=$(reports knn)" \
  "reference annotation=$(reports reference)" "tuned=$(reports tuned)" \
  "tuned + GA keyframes=$(reports tuned_kf)"
echo
echo "Ablation (tune re-run with one method left out; 'none' = one tau for all classes):"
"${TABLES[@]}" quality "tuned (all methods)=$(reports tuned)" \
  $(for a in $ABLATION; do echo "$a=$(reports "ab_$a")"; done)
echo
echo "Unknown-class rate (fraction of a left-out class's frames labelled with another class):"
rates() { for c in "$U"/*/; do for s in $SEEDS; do printf '%s,' "$c/seed${s}_$1.json"; done; done; }
"${TABLES[@]}" unknown-table "baseline=$(rates knn)" "reference=$(rates reference)" \
  "tuned=$(rates tuned)"

# --------------------------------------------------------------------------- issue 26
echo "== issue 26: the open-world protocol (foreign archives, background, confidence)"
"$here/scripts/experiment_openworld.sh" "$OUT/openworld" $SEEDS
