#!/usr/bin/env bash
# Reproduces the grasp tables of BENCHMARKS.md. Simulated: `sqscan eval --grasps` on the
# paper's scenes, clutter10 and the stacked scenes (TRIALS trials each): of the correct
# detections, those where a brute-force sampler over the true object and scene finds a valid
# grasp, how many got one, and how many first grasps are valid against the truth. Real: with
# SQSCAN_MODELS=DIR (a `benches/catalogue.sh` SQSCAN_KEEP directory), `sqscan eval-real
# --grasps` for each learned catalogue object on the learn and even test scenes (with
# SQSCAN_GRIPPER=FILE.toml, that gripper's settings instead of the default); where a found
# object gets none, whether a brute-force sampler over its fit, checked against the scan's
# points, finds one.
# Usage: benches/grasps.sh [TRIALS]   (release build; TRIALS 0 runs the real scenes alone)
set -euo pipefail
cd "$(dirname "$0")/.."
trials=${1:-100}
if [ -z "${SQSCAN:-}" ]; then
    cargo build --release --quiet --bin sqscan
    SQSCAN=target/release/sqscan
fi
sim() {
    local scene=$1 model=$2
    shift 2
    "$SQSCAN" eval --scene "scenes/$scene.toml" --model "$model" --trials "$trials" --grasps --json "$@" |
        python3 -c '
import json, sys
d = json.load(sys.stdin)
g = d["grasps"]
scene = d["scene"].split("/")[-1][:-5]
print("| %s | %s | %d | %d | %d of %d | %d of %d | %.2f | %.2f |" % (scene, d["model"], d["trials"], g["correct"],
      g["planned_where_one_exists"], g["exists"], g["first_valid"], g["planned"], g["time_ms"]["median"] or float("nan"), g["time_ms"]["p95"] or float("nan")))
'
}
[ "$trials" -gt 0 ] || sim() { :; }
[ "$trials" -eq 0 ] || echo "| scene | model | trials | correct | got a grasp where one exists | first grasp valid | median ms | p95 ms |"
[ "$trials" -eq 0 ] || echo "|---|---|---|---|---|---|---|---|"
sim fig3_table cup
sim fig3_table cup_body
sim fig3_table bowl
sim fig4_tools mallet_head
sim fig4_tools mallet_shaft
sim fig4_tools mallet
sim clutter10 cup
sim clutter10 mug
sim clutter10 spray_tin
sim clutter10 mallet
sim stacked/bowl_on_pot white_bowl
sim stacked/bowl_on_pot learned_cylinder
sim stacked/bowl_on_pot learned_box
sim stacked/mug_on_book mug
sim stacked/mug_on_book white_bowl
sim stacked/mug_on_book learned_cylinder
data=${SQSCAN_SHARED:-../shared}/data
[ -n "${SQSCAN_MODELS:-}" ] || exit 0
if [ ! -f "$data/CATALOGUE.md" ]; then
    echo "skipped the real scenes: $data/CATALOGUE.md is not here" >&2
    exit 0
fi
echo
echo "| object | scenes | found | got a grasp | first grasp sweeps no other labelled point | none, where a brute-force sampler finds one | median ms |"
echo "|---|---|---|---|---|---|---|"
for m in "$SQSCAN_MODELS"/label-*.toml; do
    id=$(basename "$m" .toml); id=${id#label-}
    for set in mosd_learn mosd_test_even; do
        "$SQSCAN" eval-real --models-dir models --labels "$data/$set/labels.json" --clouds "$data/$set" \
            --model "$m" --identity "$id" --seed 5 --grasps ${SQSCAN_GRIPPER:+--gripper "$SQSCAN_GRIPPER"} --json | python3 -c '
import json, sys
d = json.load(sys.stdin)
g = d["grasps"]
print("| %s | %s | %d | %d | %d | %d of %d | %.2f |" % (sys.argv[1], sys.argv[2], g["found"], g["with_grasp"], g["first_clear"],
      g["without_where_one_exists"], g["found"] - g["with_grasp"], g["time_ms"]["median"] or float("nan")))
' "$id" "$set"
    done
done
