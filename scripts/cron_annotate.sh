#!/usr/bin/env bash
# Unattended annotation of new motion files (issue 12): run it from cron as often as you
# like; each run does only what is new (docs/reliability.md, "Running from cron").
#
#   scripts/cron_annotate.sh INBOX/ WORK/
#
# INBOX/  motion files (.amc with their .asf, .bvh; any subfolders). Move finished files in
#         (write elsewhere, then mv): a half-copied file fails this run and is taken next time.
#         Optional: INBOX/truth.csv, ground truth of some documents.
# WORK/   mt/             class templates (mtanno learn-mt -o WORK/mt), required
#         keyframes/      keyframe queries (mtanno learn-keyframes), optional
#         classes/        class configuration folder (mtanno tune -o WORK/classes/; a folder
#                         tuned elsewhere, moved or copied here whole), optional; or
#         classes.toml    a class configuration file (its side files beside it)
#         truth.csv       ground truth, optional (used when INBOX/truth.csv is absent)
#         written here:   features/, index/, annotations/ (one table per document),
#                         reports/YYYY-MM-DD.json (today's evaluation)
#
# Stages, one log line or more each on standard output ("TIME cron_annotate: STAGE: ..."):
#   features   features of the motion files (files that are up to date are skipped), with
#              what the class configuration needs (features --classes: poses, feature set)
#   index      index add into WORK/index (index build when there is no index yet)
#   annotate   annotate --output-dir WORK/annotations (only documents whose table is
#              missing or out of date are computed)
#   evaluate   when truth exists: the annotated documents that have truth, scored into
#              WORK/reports/YYYY-MM-DD.json
#
# A run that finds another one still working (an mtanno output folder locked: exit code 3)
# logs one line and ends with its status so far, quietly: the run that holds the lock, or
# the next one, does the rest. Exit codes: 0 done; 1 some files failed (the others were
# processed; the mtanno: lines say which); 2 bad input or set-up (no WORK/mt, say); 130
# interrupted.
#
# MTANNO names the mtanno executable (default: mtanno on PATH, else the repository's .venv).
# JOBS sets --jobs of features and annotate (default 1).
set -euo pipefail

if [ $# -ne 2 ]; then
  echo "usage: $0 INBOX/ WORK/" >&2
  exit 2
fi
INBOX=${1%/}
WORK=${2%/}
here=$(cd "$(dirname "$0")/.." && pwd)
MTANNO=${MTANNO:-$(command -v mtanno || echo "$here/.venv/bin/mtanno")}
JOBS=${JOBS:-1}
status=0

log() { printf '%s cron_annotate: %s\n' "$(date '+%Y-%m-%dT%H:%M:%S%z')" "$*"; }

# stage NAME KEEP ARGS...: run mtanno ARGS; log the lines of its output that match the
# extended regular expression KEEP (its summary lines, its errors); exit code 1 is
# remembered, 3 (locked by another run) ends this run quietly, any other ends it.
stage() {
  local name=$1 keep=$2 out rc=0 line
  shift 2
  out=$("$MTANNO" "$@" 2>&1) || rc=$?
  while IFS= read -r line; do
    [[ -n $line && $line =~ $keep ]] || continue
    if [[ $line == "$name"[:\ ]* ]]; then log "$line"; else log "$name: $line"; fi
  done <<< "$out"
  case $rc in
    0) ;;
    1) status=1 ;;
    3) log "$name: another run is working here; leaving the rest to it"
       exit "$status" ;;
    *) log "$name: stopped (mtanno exit code $rc)"
       exit "$rc" ;;
  esac
}

[ -d "$INBOX" ] || { log "setup: $INBOX is not a folder"; exit 2; }
if ! ls "$WORK"/mt/*.json > /dev/null 2>&1; then
  log "setup: no class templates in $WORK/mt (mtanno learn-mt ... -o $WORK/mt)"
  exit 2
fi
if [ -z "$(find "$INBOX" -type f \( -iname '*.amc' -o -iname '*.bvh' \) -print -quit)" ]; then
  log "features: no motion files in $INBOX yet"
  exit 0
fi

classes=()
if [ -d "$WORK/classes" ]; then classes=(--classes "$WORK/classes")
elif [ -f "$WORK/classes.toml" ]; then classes=(--classes "$WORK/classes.toml"); fi

stage features . features "$INBOX" -o "$WORK/features" --jobs "$JOBS" \
  ${classes[@]+"${classes[@]}"}

if [ -f "$WORK/index/manifest.json" ]; then
  stage index . index add "$WORK/index" "$WORK/features"
else
  stage index . index "$WORK/features" -o "$WORK/index"
fi

extra=()
[ -d "$WORK/keyframes" ] && extra+=(--keyframes "$WORK/keyframes")
stage annotate . annotate --mt "$WORK/mt" ${extra[@]+"${extra[@]}"} \
  ${classes[@]+"${classes[@]}"} "$WORK/features" --output-dir "$WORK/annotations" \
  --jobs "$JOBS"

truth=
for t in "$INBOX/truth.csv" "$WORK/truth.csv"; do
  if [ -f "$t" ]; then truth=$t; break; fi
done
if [ -z "$truth" ]; then
  log "evaluate: no truth.csv in $INBOX or $WORK; nothing to evaluate"
  exit "$status"
fi
# Score only the annotated documents that have truth: the doc column of the truth table
# (mtanno's CSV: quotes only around values that need them) against the annotation tables.
truth_docs() {
  awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) { h = $i; gsub(/^[ "]+|[ "\r]+$/, "", h)
                                                  if (h == "doc") c = i }; next }
           c && NF >= c { d = $c; gsub(/^[ "]+|[ "\r]+$/, "", d); if (d != "") print d }' \
    "$1" | LC_ALL=C sort -u
}
annotated_docs() {
  find "$WORK/annotations" -type f -name '*.csv' ! -name '.*' -printf '%f\n' \
    | sed 's/\.csv$//' | LC_ALL=C sort -u
}
docs=()
while IFS= read -r d; do docs+=(--doc "$d"); done \
  < <(LC_ALL=C comm -12 <(truth_docs "$truth") <(annotated_docs))
if [ ${#docs[@]} -eq 0 ]; then
  log "evaluate: no annotated document has truth in $truth yet"
  exit "$status"
fi
report=$WORK/reports/$(date +%F).json
stage evaluate '^(overall|mtanno:)' evaluate "$WORK/annotations" --truth "$truth" \
  --json "$report" "${docs[@]}"
log "evaluate: $(( ${#docs[@]} / 2 )) documents with truth -> $report"
exit "$status"
