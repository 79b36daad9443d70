#!/usr/bin/env bash
# The detector on the real mOSD scenes of ../shared/data, scored by CATALOGUE.md's rule: for
# each model and seed, `sqscan eval-real --all` over the learn scenes and the even test scenes.
# Prints one markdown row per model and scene set (recall overall, stacked, upside-down; false
# answers over the queries; the median and p95 of the per-query times over all runs).
# Usage: benches/eval_real.sh [SEEDS] [MODEL:CLASS ...]   (release build; SEEDS e.g. "1 2 3")
#   default: seeds 1-8, mug:mug white_bowl:white_bowl learned_mug:mug learned_white_bowl:white_bowl
#   SQSCAN=path/to/sqscan runs another binary (to compare builds).
set -euo pipefail
cd "$(dirname "$0")/.."
seeds=${1:-"1 2 3 4 5 6 7 8"}
shift || true
queries=("$@")
[ ${#queries[@]} -gt 0 ] || queries=(mug:mug white_bowl:white_bowl learned_mug:mug learned_white_bowl:white_bowl)
data=${SQSCAN_SHARED:-../shared}/data
if [ ! -d "$data/mosd_learn" ]; then
    echo "skipped: $data/mosd_learn is not here" >&2
    exit 0
fi
if [ -z "${SQSCAN:-}" ]; then
    cargo build --release --quiet --bin sqscan
    SQSCAN=target/release/sqscan
fi
echo "| scenes | model as class | seeds | found | stacked | upside-down | false answers / queries | median ms | p95 ms |"
echo "|---|---|---|---|---|---|---|---|---|"
for set in mosd_learn mosd_test_even; do
    for q in "${queries[@]}"; do
        model=${q%%:*} class=${q##*:}
        for seed in $seeds; do
            "$SQSCAN" eval-real --models-dir models --labels "$data/$set/labels.json" --clouds "$data/$set" \
                --model "$model" --class "$class" --seed "$seed" --json
        done | python3 -c '
import json, sys
runs = [json.loads(l) for l in sys.stdin if l.strip()]
def tot(key, sub=None):
    f = o = 0
    for r in runs:
        c = r["recall"][key] if sub is None else r["recall"][key].get(sub, {"found": 0, "of": 0})
        f += c["found"]; o += c["of"]
    return "%d of %d" % (f, o)
fa = sum(r["false_answers"] for r in runs)
q = sum(r["scenes"] for r in runs)
import statistics
med = statistics.median(r["time_ms"]["median"] for r in runs)
p95 = max(r["time_ms"]["p95"] for r in runs)
print("| %s | %s as %s | %s | %s | %s | %s | %d / %d | %.1f | %.1f |" % (sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], tot("all"), tot("by_support", "stacked"), tot("upside_down"), fa, q, med, p95))
' "$set" "$model" "$class" "${seeds// /,}"
    done
done
