#!/usr/bin/env python3
"""Hostile clients against sqscand (issue 18): idle and slowloris clients that would lock
others out, and slow `watch` readers that would grow the daemon's memory.

Starts target/release/sqscand on the simulated Fig. 3 scene (no hardware) with a socket in a
temporary directory, then:
  1. attaches IDLE idle clients and SLOW slowloris clients (one byte every 2 s, never a whole
     line) and times `sqscan find cup` from a new client;
  2. lets WATCHERS clients watch cup and bowl and never read, first asking with a 60 KB id
     (refused), then with a 250-byte one; samples the daemon's RSS while they are attached and
     after they leave.
Prints one JSON line of figures. Usage: benches/clients.py [IDLE SLOW WATCHERS]
(default 1024 200 120). Needs `cargo build --release` first and `ulimit -n` above
IDLE + SLOW + 100."""

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IDLE, SLOW, WATCHERS = (int(a) for a in (sys.argv[1:4] if len(sys.argv) >= 4 else (1024, 200, 120)))


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def connect(path):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(path)
    return s


def main():
    tmp = tempfile.mkdtemp(prefix="sqscan-clients-")
    sock = os.path.join(tmp, "sqscand.sock")
    cfg = os.path.join(tmp, "sqscand.toml")
    with open(cfg, "w") as f:
        f.write(
            f'[sim]\nscene = "{ROOT}/scenes/fig3_table.toml"\nseed = 3\nrealtime = false\n'
            "[sweep]\npause_s = 0.3\n"
        )
    daemon = subprocess.Popen(
        [f"{ROOT}/target/release/sqscand", "--config", cfg, "--socket", sock],
        stdout=subprocess.DEVNULL,
        stderr=open(os.path.join(tmp, "sqscand.log"), "w"),
    )
    try:
        for _ in range(300):
            if os.path.exists(sock):
                break
            time.sleep(0.1)
        sqscan = [f"{ROOT}/target/release/sqscan", "find", "cup", "--socket", sock, "--json"]
        # A first sweep, so that the timed find is a find and not a wait for the simulator.
        subprocess.run(sqscan + ["--timeout", "60"], check=True, capture_output=True)
        time.sleep(1.0)
        rss_start = rss_mb(daemon.pid)

        # 1. Idle and slowloris clients, then a find from a new client.
        idle = [connect(sock) for _ in range(IDLE)]
        slow = [connect(sock) for _ in range(SLOW)]
        stop = threading.Event()

        def drip():
            msg = b'{"cmd":"status"'
            k = 0
            while not stop.is_set():
                for s in slow:
                    try:
                        s.send(msg[k % len(msg) : k % len(msg) + 1])
                    except OSError:
                        pass
                k += 1
                stop.wait(2.0)

        dripper = threading.Thread(target=drip)
        dripper.start()
        time.sleep(1.0)
        t0 = time.monotonic()
        r = subprocess.run(sqscan + ["--timeout", "30"], capture_output=True, text=True)
        find_s = time.monotonic() - t0
        answer = r.stdout.strip().splitlines()[-1] if r.stdout.strip() else r.stderr.strip()
        found = '"found":true' in answer
        stop.set()
        dripper.join()
        for s in idle + slow:
            s.close()
        time.sleep(1.0)

        # 2. Slow watch readers: a 60 KB id is refused; a 250-byte one watches and never reads.
        # A reader that keeps up watches first, so that the detector's own working memory (its
        # threads' arenas) is there before the slow readers come, as on a daemon in service.
        s = connect(sock)
        s.sendall(b'{"cmd":"watch","objects":["cup","bowl"]}\n')
        f = s.makefile("rb")
        for _ in range(12):
            f.readline()
        s.close()
        time.sleep(2.0)
        rss_before_watchers = rss_mb(daemon.pid)
        big_refused = 0
        watchers = []
        for k in range(WATCHERS):
            s = connect(sock)
            s.settimeout(10)
            s.recv(4096)  # the version line
            s.sendall((json.dumps({"cmd": "watch", "objects": ["cup", "bowl"], "id": "x" * 60000}) + "\n").encode())
            if b"over the limit" in s.recv(4096):
                big_refused += 1
            s.sendall((json.dumps({"cmd": "watch", "objects": ["cup", "bowl"], "id": "y" * 248}) + "\n").encode())
            # Shrink the socket's buffers so that the daemon's queue is what fills.
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            watchers.append(s)
        peak = 0.0
        t_end = time.monotonic() + 30.0
        while time.monotonic() < t_end:
            peak = max(peak, rss_mb(daemon.pid))
            time.sleep(0.5)
        with_watchers = rss_mb(daemon.pid)
        for s in watchers:
            s.close()
        time.sleep(5.0)
        after = rss_mb(daemon.pid)
        status = subprocess.run(
            [f"{ROOT}/target/release/sqscan", "status", "--socket", sock, "--json"], capture_output=True, text=True
        ).stdout
        print(
            json.dumps(
                {
                    "idle": IDLE,
                    "slowloris": SLOW,
                    "find_s": round(find_s, 3),
                    "find_found": found,
                    "watchers": WATCHERS,
                    "big_id_refused": big_refused,
                    "rss_mb": {
                        "start": round(rss_start, 1),
                        "before_watchers": round(rss_before_watchers, 1),
                        "peak_with_watchers": round(peak, 1),
                        "with_watchers": round(with_watchers, 1),
                        "after": round(after, 1),
                    },
                    "status_tail": status.strip()[-300:],
                }
            )
        )
    finally:
        daemon.terminate()
        daemon.wait(timeout=10)


if __name__ == "__main__":
    main()
