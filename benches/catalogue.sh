#!/usr/bin/env bash
# Learns every object of ../shared/data/CATALOGUE.md that has a listed view, from that view
# (`sqscan learn --label GROUP`, and again with `--at` the group's labelled centroid), then looks
# for each in every scene of the learn and the even test sets (`sqscan eval-real --identity ID
# --all`, the learned view neutral) and prints the table of BENCHMARKS.md: instances found,
# those resting on another object, false answers per queries, and the times.
# Usage: benches/catalogue.sh [SEED] [label|at ...]   (release build; default seed 5, both ways)
#   SQSCAN=path/to/sqscan runs another binary; SQSCAN_VIEWS=FILE takes the views from FILE
#   (lines "identity scene group", # comments; benches/second_views.txt holds the second views
#   BENCHMARKS.md reports) instead of CATALOGUE.md's column; SQSCAN_KEEP=DIR keeps the
#   learned models and the answers (eval-real's JSON) in DIR.
set -euo pipefail
cd "$(dirname "$0")/.."
seed=${1:-5}
shift || true
ways=("$@")
[ ${#ways[@]} -gt 0 ] || ways=(label at)
data=${SQSCAN_SHARED:-../shared}/data
if [ ! -f "$data/CATALOGUE.md" ]; then
    echo "skipped: $data/CATALOGUE.md is not here" >&2
    exit 0
fi
if [ -z "${SQSCAN:-}" ]; then
    cargo build --release --quiet --bin sqscan
    SQSCAN=target/release/sqscan
fi
work=$(mktemp -d /tmp/sqscan-catalogue.XXXXXX)
# SQSCAN_KEEP=DIR keeps the learned models and eval-real's JSON answers there.
trap 'if [ -n "${SQSCAN_KEEP:-}" ]; then mkdir -p "$SQSCAN_KEEP" && cp "$work"/*.json "$work"/*.toml "$SQSCAN_KEEP"/ 2>/dev/null || true; fi; rm -rf "$work"' EXIT
if [ -n "${SQSCAN_VIEWS:-}" ]; then
    grep -v '^#' "$SQSCAN_VIEWS" > "$work/views"
else
    # "| identity | ... | learnN, G | ..." rows
    python3 - "$data/CATALOGUE.md" > "$work/views" <<'PY'
import re, sys
for line in open(sys.argv[1]):
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    for c in cells:
        m = re.fullmatch(r"(learn\d+), (\d+)", c)
        if m:
            print(cells[0], m.group(1), m.group(2))
PY
fi
for way in "${ways[@]}"; do
    : > "$work/rows-$way"
    while read -r id scene group; do
        model="$work/$way-$id.toml"
        case $way in
            label) how=(--label "$group") ;;
            at) how=(--at "$(python3 -c '
import json, sys
for s in json.load(open(sys.argv[1])):
    if s["scene"] == sys.argv[2]:
        for o in s["objects"]:
            if o.get("group") == int(sys.argv[3]):
                print(",".join("%.4f" % c for c in o["centroid"]))
' "$data/mosd_learn/labels.json" "$scene" "$group")") ;;
            *) echo "unknown way $way (label or at)" >&2; exit 2 ;;
        esac
        start=$(date +%s.%N)
        if ! "$SQSCAN" learn --cloud "$data/mosd_learn/$scene.pcd" "${how[@]}" --name "$id" --out "$model" --force \
            > "$work/learn.json" 2> "$work/learn.err"; then
            echo "$id: learning failed: $(tail -1 "$work/learn.err")" >&2
            echo "$id $scene failed" >> "$work/rows-$way"
            continue
        fi
        end=$(date +%s.%N)
        for set in mosd_learn mosd_test_even; do
            learned=()
            [ $set = mosd_learn ] && learned=(--learned-from "$scene:$group")
            "$SQSCAN" eval-real --models-dir models --labels "$data/$set/labels.json" --clouds "$data/$set" \
                --model "$model" --identity "$id" --seed "$seed" --json "${learned[@]}" > "$work/$way-$id-$set.json"
        done
        python3 - "$id" "$scene" "$start" "$end" "$work/learn.json" "$work/$way-$id-mosd_learn.json" \
            "$work/$way-$id-mosd_test_even.json" >> "$work/rows-$way" <<'PY'
import json, sys
id, scene, t0, t1, learned = sys.argv[1:6]
l = json.load(open(learned))
shape = l["parts"][0]
print(json.dumps({"id": id, "scene": scene, "learn_s": float(t1) - float(t0),
    "a": shape["a"], "e1": shape["e1"], "e2": shape["e2"], "open": shape["open"],
    "sets": [json.load(open(f)) for f in sys.argv[6:]]}))
PY
    done < "$work/views"
    echo
    echo "Learned with --$way (seed $seed):"
    python3 - "$work/rows-$way" <<'PY'
import json, statistics, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
failed = [l.split()[0] for l in open(sys.argv[1]) if not l.startswith("{")]
print("| object | learned from | shape a (mm), e1, e2 | learn s | learn scenes: found, stacked, false | even test scenes: found, stacked, false |")
print("|---|---|---|---|---|---|")
tot = {}
for r in rows:
    cells = []
    for k, s in enumerate(r["sets"]):
        a, st = s["recall"]["all"], s["recall"]["by_support"].get("stacked", {"found": 0, "of": 0})
        t = tot.setdefault(k, [0, 0, 0, 0, 0, 0, []])
        for i, v in enumerate([a["found"], a["of"], st["found"], st["of"], s["false_answers"], s["scenes"]]):
            t[i] += v
        t[6].append(s["time_ms"]["median"])
        cells.append("%d of %d, %d of %d, %d" % (a["found"], a["of"], st["found"], st["of"], s["false_answers"]))
    print("| %s | %s | %s, %.2f, %.2f%s | %.1f | %s |" % (r["id"], r["scene"], "x".join("%.0f" % (2e3 * x) for x in r["a"]),
        r["e1"], r["e2"], ", open" if r["open"] else "", r["learn_s"], " | ".join(cells)))
print()
print("| scenes | instances found | resting on another object | false answers | query median ms |")
print("|---|---|---|---|---|")
for k, name in [(0, "learn scenes (mosd_learn)"), (1, "even test scenes (mosd_test_even)")]:
    t = tot.get(k)
    if t:
        print("| %s | %d of %d (%.0f %%) | %d of %d | %d in %d queries | %.1f |" % (name, t[0], t[1], 100.0 * t[0] / max(t[1], 1),
            t[2], t[3], t[4], t[5], statistics.median(t[6])))
if rows:
    print()
    print("learning: median %.2f s over %d objects%s" % (statistics.median(r["learn_s"] for r in rows), len(rows),
        (", failed: " + ", ".join(failed)) if failed else ""))
PY
done
