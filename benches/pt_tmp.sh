#!/usr/bin/env bash
# Reproduces the detection table of BENCHMARKS.md: `sqscan eval` on the paper's scenes, 100
# trials each (new sensor noise and a new search seed per trial), with the object and without.
# Usage: benches/paper_tables.sh [TRIALS]   (release build; prints one markdown row per run)
set -euo pipefail
cd "$(dirname "$0")/.."
trials=${1:-100}
:
bin=${SQBIN}
row() {
    local scene=$1 model=$2 absent=${3:-}
    $bin eval --scene "scenes/$scene.toml" --model "$model" --trials "$trials" --json $absent |
        python3 -c '
import json, sys
d = json.load(sys.stdin)
scene = d["scene"].split("/")[-1][:-5]
t = d["time_ms"]
if d["absent"]:
    print("| %s | %s (absent) | %d | | %d false found | %.1f | %.1f | | |" % (scene, d["model"], d["trials"], d["false_found"], t["median"], t["p95"]))
else:
    p, r = d["position_error_m"], d["rotation_error_deg"]
    print("| %s | %s | %d | %.0f %% | %d found | %.1f | %.1f | %.2f / %.2f | %.2f / %.2f |" % (scene, d["model"], d["trials"], 100 * d["detection_rate"], d["found"], t["median"], t["p95"], 1e3 * p["median"], 1e3 * p["p95"], r["median"], r["p95"]))
'
}
echo "| scene | model | trials | correct | found | median ms | p95 ms | position error mm (median / p95) | rotation error deg (median / p95) |"
echo "|---|---|---|---|---|---|---|---|---|"
row fig3_table bowl
row fig3_table cup
row fig3_table cup_body
row fig4_tools mallet_head
row fig4_tools mallet_shaft
row fig4_tools mallet
row fig3_table bowl --absent
row fig3_table cup --absent
row fig3_table cup_body --absent
row fig4_tools mallet_head --absent
row fig4_tools mallet_shaft --absent
row fig4_tools mallet --absent
# The single mallet parts with nothing of their shape left on the table (see the scene's header).
row fig4_no_lookalikes mallet_head --absent
row fig4_no_lookalikes mallet_shaft --absent
