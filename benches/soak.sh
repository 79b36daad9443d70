#!/usr/bin/env bash
# A soak run of sqscand on the mock rig: honest `find`s all along and a fault injected every
# minute (benches/soak.py says which, what counts as recovered and what fails the run).
#
#   benches/soak.sh --minutes 60            # the run BENCHMARKS.md reports
#   benches/soak.sh --minutes 2 --fault-every 20
#
# Builds the release binaries first, unless SQSCAN_BIN names a directory holding sqscan and
# sqscand. Prints a JSON report; exits 1 when the run fails.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${SQSCAN_BIN:-}" ]; then
    cargo build --release --locked --bins >&2
    SQSCAN_BIN=target/release
fi
exec python3 benches/soak.py --bin "$SQSCAN_BIN" "$@"
