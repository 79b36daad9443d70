#!/usr/bin/env bash
# The README's test command: every test of every feature. Installs the Debian packages the
# feature tests need when they are missing (as root, with apt-get), then runs cargo test with
# every feature. Plain `cargo test` (no features) needs none of this and stays pure Rust.
set -euo pipefail
cd "$(dirname "$0")/.."

# gige: aravis (its library, and its camera emulator the tests serve on loopback); libusb is a
# build dependency of aravis-sys that libaravis-dev does not pull in.
packages=(pkg-config libaravis-dev libusb-1.0-0-dev)
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
        echo "test.sh: missing ${missing[*]}; install them (apt-get install ${missing[*]}) or run as root" >&2
        exit 1
    fi
    echo "test.sh: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The GigE Vision tests run inside a private network namespace with only loopback (unshare -n,
# root): they say SKIPPED where none can be had.
cargo test --workspace --locked --all-features
