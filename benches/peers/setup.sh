#!/usr/bin/env bash
# Installs the peer benchmark's Python side (Open3D, CPU build, and numpy) into its own venv, so
# nothing of it touches the system Python or `cargo test`. Idempotent: a second run only checks
# the imports and returns in about a second.
# Usage: benches/peers/setup.sh            (venv in $PEERS_VENV, default target/peers-venv)
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=${PEERS_VENV:-target/peers-venv}
open3d_version=${PEERS_OPEN3D_VERSION:-0.20.0}
python=${PYTHON:-python3}

check() {
    "$venv/bin/python" - "$open3d_version" <<'EOF' 2>/dev/null
import sys
import numpy
import open3d
sys.exit(0 if open3d.__version__ == sys.argv[1] else 1)
EOF
}

if [ -x "$venv/bin/python" ] && check; then
    echo "peers venv ready: $venv (open3d $open3d_version)"
    exit 0
fi
# The Open3D wheel links libusb (for its Azure Kinect reader) although nothing here uses it; the
# import fails without it. Debian's package is the only system dependency.
if ! ldconfig -p | grep 'libusb-1.0.so.0' >/dev/null; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        apt-get install -y -qq libusb-1.0-0 >/dev/null || { apt-get update -qq && apt-get install -y -qq libusb-1.0-0 >/dev/null; }
    else
        echo "setup.sh: Open3D needs libusb-1.0.so.0: install it (Debian: apt-get install libusb-1.0-0)" >&2
        exit 1
    fi
fi
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --upgrade pip
# open3d-cpu is Open3D built without CUDA: the benchmark uses only the CPU pipelines. numpy is
# left for pip to resolve against the wheel.
"$venv/bin/python" -m pip install --quiet "open3d-cpu==$open3d_version" numpy
check || { echo "setup.sh: open3d $open3d_version does not import from $venv" >&2; exit 1; }
echo "peers venv ready: $venv (open3d $open3d_version)"
