#!/usr/bin/env bash
# The README's test command: every test of every feature. Installs the Debian packages the
# feature tests need when they are missing (as root, with apt-get), then runs cargo test with
# every feature. Plain `cargo test` (no features) needs none of this and stays pure Rust.
set -euo pipefail
cd "$(dirname "$0")/.."

# gige: aravis (its library, and its camera emulator the tests serve on loopback); libusb is a
# build dependency of aravis-sys that libaravis-dev does not pull in. lintian: the package test
# (tests/package/main.rs) checks the Debian package with it. python3-seccomp: the ROS 2 test refuses
# netlink sockets to the daemon as systemd's RestrictAddressFamilies does.
packages=(pkg-config libaravis-dev libusb-1.0-0-dev lintian python3-seccomp)
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

# cargo-deb builds the Debian package (crates.io; it is not a Debian package).
if ! cargo deb --version >/dev/null 2>&1; then
    echo "test.sh: installing cargo-deb"
    cargo install --locked cargo-deb@3.8.0
fi
# The package test fails, instead of skipping, where its tools are missing.
export SQSCAN_REQUIRE_PACKAGE_TOOLS=1

# The MCAP, live-view and ROS 2 tests check the daemon with independent readers from PyPI (mcap,
# mcap-ros2-support's ROS 2 decoder, rosbags for the recordings as rosbag2 bags, websockets for a
# Foxglove client, and Eclipse Cyclone DDS, whose wheel carries its C library), in a venv of
# their own under target/.
venv=target/py-venv
if ! "$venv/bin/python" -c "import mcap, mcap_ros2, rosbags, websockets, cyclonedds" >/dev/null 2>&1; then
    echo "test.sh: making $venv (PyPI: mcap, mcap-ros2-support, rosbags, websockets, cyclonedds)"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check \
        mcap==1.6.0 mcap-ros2-support==0.6.0 rosbags==0.11.9 websockets==15.0.1 cyclonedds==11.0.1
fi
export SQSCAN_PYTHON="$PWD/$venv/bin/python"
export SQSCAN_REQUIRE_PYTHON_TOOLS=1

# The live-view tests also check the daemon with npm's @foxglove/ws-protocol client (as older
# Foxglove viewers and Lichtblick connect), installed from tests/js's lock file under target/.
if ! command -v npm >/dev/null 2>&1; then
    if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
        echo "test.sh: npm is missing; install Node.js and npm (apt-get install nodejs npm)" >&2
        exit 1
    fi
    echo "test.sh: installing nodejs npm"
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends nodejs npm
fi
js=target/js-clients
if ! cmp -s tests/js/package-lock.json "$js/package-lock.json" || [ ! -d "$js/node_modules/@foxglove/ws-protocol" ]; then
    echo "test.sh: installing the npm test clients into $js (tests/js/package-lock.json)"
    rm -rf "$js"
    mkdir -p "$js"
    cp tests/js/package.json tests/js/package-lock.json "$js/"
    (cd "$js" && npm ci --no-audit --no-fund --silent)
fi
export SQSCAN_NODE_MODULES="$PWD/$js/node_modules"
export SQSCAN_REQUIRE_NODE_TOOLS=1

# Lints first: clippy and rustdoc clean under -D warnings, every target and feature (the lints
# allowed on purpose are in Cargo.toml's [workspace.lints], each with its reason).
cargo clippy --workspace --all-targets --all-features --locked -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --document-private-items --all-features --locked

# The GigE Vision and ROS 2 (DDS) tests run inside a private network namespace with only loopback
# (unshare -n, root): plain `cargo test` says SKIPPED where none can be had; here they fail.
export SQSCAN_REQUIRE_NETNS=1
cargo test --workspace --locked --all-features
