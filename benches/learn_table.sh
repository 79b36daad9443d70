#!/usr/bin/env bash
# The error table of `sqscan learn` on simulated single-object scans: every shipped
# single-part model alone on the table of the fig3 rig (2 mm noise at 1 m), learned from one
# sweep, compared with the truth after matching the learned axes to the true ones.
# Usage: benches/learn_table.sh [SEED [LEARN OPTIONS...]] (build with `cargo build --release` first),
# e.g. `benches/learn_table.sh 1 --cost radial`
set -euo pipefail
cd "$(dirname "$0")/.."
seed="${1:-1}"
shift || true
bin=target/release/sqscan
echo "| model | true a1 a2 a3 (mm) | learned a1 a2 a3 (mm) | max size error (mm) | true e1 e2 | learned e1 e2 | max e error | z axis matched | object points | rms (mm) | s | within 5 mm / 0.1 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for f in models/*.toml; do
    m=$(basename "$f" .toml)
    case "$m" in learned_*) continue ;; esac   # models learned by `sqscan learn` are not truth
    [ "$(grep -c '^\[\[part\]\]' "$f")" = 1 ] || continue
    "$bin" learn --simulate "$m" --seed "$seed" "$@" | python3 -c '
import json, sys
r = json.load(sys.stdin)
t, l, e = r["truth"], r["learned"], r["errors"]
ax = e["axis_of"]
mm = lambda v: " ".join("%.1f" % (1000 * x) for x in v)
print("| %s | %s | %s | %.1f | %.2f %.2f | %.2f %.2f | %.2f | %s | %d | %.2f | %.1f | %s |" % (
    r["model"], mm(t["a"]), mm([l["a"][ax[k]] for k in range(3)]), 1000 * r["max_size_error_m"],
    t["e1"], t["e2"], l["e1"], l["e2"], r["max_exponent_error"], "yes" if e["z_matches"] else "no",
    r["object_points"], 1000 * r["rms_m"], r["seconds"], "yes" if r["within_tolerance"] else "**no**"))
'
done
