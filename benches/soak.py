#!/usr/bin/env python3
"""A soak run of sqscand on the mock rig (benches/soak.sh runs it; see BENCHMARKS.md).

The daemon scans continuously from `sqscan mock rig` (a PowerCube PTU and an SQPF sensor on
pseudo-terminals) while honest clients ask `find cup` all along, each on its own connection,
one request after another (the first always of the next sweep, the others ten times a second of
the newest). Every `--fault-every` seconds a fault is injected, in turn:

- hostile: a burst of clients (garbage bytes, half a request that never ends, a 2 MB line,
  clouds asked for and never read), all closed after a few seconds;
- unplug: the rig's process ends (both devices vanish) and comes back 3 s later on the same links;
- sighup: the daemon reloads its configuration;
- stall: the rig's process is stopped for 6 s (the sensor and the PTU go silent), then resumed;
- garbage: the rig comes back sending garbage bytes before every 3rd sensor frame and every 5th
  PTU reply for 20 s, then plain again.

A fault is recovered when, after it ends, the devices are all `ok` and a sweep that began after
its end has completed (for sighup and hostile: when the reload is counted without an error and
`status` is answered). Descriptors and resident memory are sampled at quiet moments (just before
each fault, and at the end).

Fails (exit 1) on any lost answer (a request with no reply within 90 s, or a connection closed
before its reply), a fault not recovered within 60 s, a daemon that does not stop cleanly, or a
leak: descriptors at the end not those of the first quiet sample after the warm-up (5 minutes,
or a quarter of a shorter run), resident memory more than 10 MB above it, or (runs of 20 minutes
and more) growing by 50 KB a minute or more after the warm-up (least-squares slope).
Prints a JSON report on stdout.
"""
import argparse
import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def now():
    return time.monotonic()


class Honest(threading.Thread):
    """One client asking `find cup` in a loop on one connection (a new one if it is closed): the
    first of them always of the next sweep (`max_age_s` 0), the others of one at most 10 s old,
    ten times a second."""

    def __init__(self, socket_path, stop, k):
        super().__init__(daemon=True)
        self.path, self.stop, self.k = socket_path, stop, k
        self.asked = self.answered = self.found = self.lost = 0
        self.codes = {}
        self.lost_why = []

    def connect(self):
        s = socket.socket(socket.AF_UNIX)
        s.settimeout(90)
        s.connect(self.path)
        f = s.makefile("rwb")
        json.loads(f.readline())  # the version greeting
        return s, f

    def run(self):
        s = f = None
        n = 0
        while not self.stop.is_set():
            try:
                if f is None:
                    s, f = self.connect()
            except OSError:
                time.sleep(0.5)
                continue
            n += 1
            rid = f"h{self.k}-{n}"
            fresh = self.k == 0
            req = {"cmd": "find", "object": "cup", "max_age_s": 0.0 if fresh else 10.0, "timeout_s": 30, "id": rid}
            self.asked += 1
            try:
                f.write((json.dumps(req) + "\n").encode())
                f.flush()
                line = f.readline()
                if not line:
                    raise OSError("connection closed before the reply")
                reply = json.loads(line)
                if reply.get("id") != rid:
                    raise OSError(f"a reply to another request: {line[:200]!r}")
                self.answered += 1
                if not fresh:
                    time.sleep(0.1)
                if reply.get("class") == "detection":
                    self.found += reply.get("found") is True
                else:
                    code = reply.get("code", reply.get("class"))
                    self.codes[code] = self.codes.get(code, 0) + 1
                    time.sleep(0.2)
            except (OSError, ValueError) as e:
                self.lost += 1
                self.lost_why.append(f"{rid}: {e}")
                try:
                    s.close()
                except OSError:
                    pass
                s = f = None
        if s is not None:
            s.close()


def ask(path, req, timeout=30):
    s = socket.socket(socket.AF_UNIX)
    s.settimeout(timeout)
    s.connect(path)
    f = s.makefile("rwb")
    f.readline()
    f.write((json.dumps(req) + "\n").encode())
    f.flush()
    reply = json.loads(f.readline())
    s.close()
    return reply


def sample(pid):
    fds = len(os.listdir(f"/proc/{pid}/fd"))
    rss = 0
    with open(f"/proc/{pid}/status") as st:
        for line in st:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) * 1024
    return fds, rss


class Rig:
    def __init__(self, bin_dir, work):
        self.bin_dir, self.work = bin_dir, work
        self.ptu, self.sensor = os.path.join(work, "ptu"), os.path.join(work, "sensor")
        self.proc = None
        self.log = open(os.path.join(work, "rig.log"), "ab")

    def start(self, extra=()):
        for p in (self.ptu, self.sensor):
            if os.path.lexists(p):
                os.unlink(p)
        self.proc = subprocess.Popen(
            [os.path.join(self.bin_dir, "sqscan"), "mock", "rig", "--protocol", "powercube",
             "--scene", os.path.join(ROOT, "scenes/fig3_table.toml"),
             "--ptu-link", self.ptu, "--sensor-link", self.sensor, *extra],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=self.log,
            env={**os.environ, "SQSCAN_MODELS_DIR": os.path.join(ROOT, "models")})
        deadline = now() + 30
        while not (os.path.exists(self.ptu) and os.path.exists(self.sensor)):
            if now() > deadline:
                raise SystemExit("soak: the mock rig's links did not appear")
            time.sleep(0.05)

    def stop(self):
        if self.proc is not None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.proc = None


def hostile_burst(path, seed):
    """Clients a broken or hostile peer would send; closed after a few seconds."""
    rng = random.Random(seed)
    socks = []
    for k in range(200):
        try:
            s = socket.socket(socket.AF_UNIX)
            s.setblocking(True)
            s.settimeout(2)
            s.connect(path)
            kind = k % 5
            if kind == 0:
                s.sendall(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 512))))
            elif kind == 1:
                s.sendall(b'{"cmd":"fi')  # half a request, never finished
            elif kind == 2 and k < 40:
                s.sendall(b"x" * (2 << 20) + b"\n")
            elif kind == 3:
                s.sendall(b'{"cmd":"cloud","max_age_s":3600}\n' * 8)  # never read
            else:
                s.sendall(b'{"cmd":"models"}\n' * 50)  # never read
            socks.append(s)
        except OSError:
            pass
    time.sleep(4)
    for s in socks:
        s.close()


def recovered_devices(path, after_wall):
    st = ask(path, {"cmd": "status"})
    ok = all(d.get("state") == "ok" for d in st.get("devices", []))
    last = st.get("last_sweep") or {}
    began = (last.get("time") or 0) - (last.get("duration_s") or 0)
    return ok and began > after_wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=60)
    ap.add_argument("--fault-every", type=float, default=60, help="seconds between faults")
    ap.add_argument("--clients", type=int, default=2, help="honest clients")
    ap.add_argument("--bin", required=True, help="directory of sqscan and sqscand")
    ap.add_argument("--work", help="directory for the run's files (default: a new temporary one)")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="sqscan-soak-")
    os.makedirs(work, exist_ok=True)
    duration = a.minutes * 60
    warmup = min(300.0, duration / 4)

    rig = Rig(a.bin, work)
    rig.start()
    sock = os.path.join(work, "sqscand.sock")
    config = os.path.join(work, "sqscand.toml")
    with open(config, "w") as c:
        c.write(f"""[hardware]
calibration = "{ROOT}/calibration/sim_rig.toml"
ptu = {{ path = "{rig.ptu}", protocol = "powercube" }}
sensor = {{ path = "{rig.sensor}" }}
[sweep]
tilt_from_rad = 0.49
tilt_to_rad = 0.84
speed_rad_s = 0.12
timeout_s = 5.0
""")
    daemon_log = open(os.path.join(work, "sqscand.log"), "wb")
    daemon = subprocess.Popen(
        [os.path.join(a.bin, "sqscand"), "--config", config, "--socket", sock],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=daemon_log,
        env={k: v for k, v in {**os.environ, "SQSCAN_MODELS_DIR": os.path.join(ROOT, "models")}.items()
             if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC")})
    deadline = now() + 30
    while True:
        try:
            ask(sock, {"cmd": "status"}, 5)
            break
        except OSError:
            if now() > deadline or daemon.poll() is not None:
                raise SystemExit("soak: the daemon did not start; see " + work)
            time.sleep(0.1)

    stop = threading.Event()
    honest = [Honest(sock, stop, k) for k in range(a.clients)]
    for h in honest:
        h.start()
    start = now()
    samples = []  # (t_s, fds, rss)
    faults = []
    kinds = ["hostile", "unplug", "sighup", "stall", "garbage"]
    k = 0
    next_fault = a.fault_every
    while now() - start < duration:
        wait = min(next_fault, duration) - (now() - start)
        if wait > 0:
            time.sleep(min(wait, 1.0))
            continue
        if next_fault >= duration:
            break
        t = now() - start
        fds, rss = sample(daemon.pid)
        samples.append((round(t, 1), fds, rss))
        kind = kinds[k % len(kinds)]
        k += 1
        began_wall = time.time()
        reloads = ask(sock, {"cmd": "status"})["config"]["reloads"] if kind == "sighup" else 0
        if kind == "hostile":
            hostile_burst(sock, a.seed + k)
        elif kind == "unplug":
            rig.stop()
            time.sleep(3)
            rig.start()
        elif kind == "sighup":
            daemon.send_signal(signal.SIGHUP)
        elif kind == "stall":
            rig.proc.send_signal(signal.SIGSTOP)
            time.sleep(6)
            rig.proc.send_signal(signal.SIGCONT)
        elif kind == "garbage":
            rig.stop()
            rig.start(["--sensor-garbage-every", "3", "--garbage-every", "5", "--seed", str(a.seed + k)])
            time.sleep(20)
            rig.stop()
            rig.start()
        ended_wall = time.time()
        ended = now()
        recovered = None
        while now() - ended < 60:
            try:
                if kind == "sighup":
                    cfg = ask(sock, {"cmd": "status"})["config"]
                    ok = cfg["reloads"] > reloads and cfg.get("reload_error") is None
                elif kind == "hostile":
                    ok = ask(sock, {"cmd": "status"})["class"] == "status"
                else:
                    ok = recovered_devices(sock, ended_wall)
            except (OSError, ValueError, KeyError):
                ok = False
            if ok:
                recovered = round(now() - ended, 2)
                break
            time.sleep(0.25)
        faults.append({"kind": kind, "at_s": round(t, 1), "lasted_s": round(ended_wall - began_wall, 1),
                       "recovered_after_s": recovered})
        next_fault += a.fault_every
    # A quiet moment at the end: the last fault has been recovered from.
    time.sleep(max(0.0, 5.0))
    fds, rss = sample(daemon.pid)
    samples.append((round(now() - start, 1), fds, rss))
    stop.set()
    for h in honest:
        h.join(100)
    daemon.send_signal(signal.SIGTERM)
    try:
        code = daemon.wait(15)
    except subprocess.TimeoutExpired:
        daemon.kill()
        code = "did not stop within 15 s"
    rig.stop()

    after = [s for s in samples if s[0] >= warmup] or samples[-1:]
    ref, end = after[0], samples[-1]
    slope = None
    if len(after) >= 3:
        xs = [s[0] / 60 for s in after]
        ys = [s[2] for s in after]
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        sxx = sum((x - mx) ** 2 for x in xs)
        slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else 0.0
    failures = []
    lost = sum(h.lost for h in honest)
    if lost:
        failures.append(f"{lost} answers lost: " + "; ".join(sum((h.lost_why for h in honest), [])[:5]))
    for f in faults:
        if f["recovered_after_s"] is None:
            failures.append(f"{f['kind']} at {f['at_s']} s not recovered within 60 s")
    if code != 0:
        failures.append(f"the daemon's stop: exit {code}")
    if end[1] != ref[1]:
        failures.append(f"descriptors {ref[1]} at {ref[0]} s but {end[1]} at the end")
    if end[2] - ref[2] > 10 << 20:
        failures.append(f"RSS {ref[2] >> 10} KiB at {ref[0]} s but {end[2] >> 10} KiB at the end")
    if duration >= 20 * 60 and slope is not None and slope >= 50_000:
        failures.append(f"RSS grows {slope / 1000:.1f} KB a minute after the warm-up")
    report = {
        "minutes": a.minutes,
        "fault_every_s": a.fault_every,
        "asked": sum(h.asked for h in honest),
        "answered": sum(h.answered for h in honest),
        "found": sum(h.found for h in honest),
        "lost": lost,
        "error_replies": {c: sum(h.codes.get(c, 0) for h in honest) for c in sorted({c for h in honest for c in h.codes})},
        "faults": faults,
        "recovered": sum(f["recovered_after_s"] is not None for f in faults),
        "samples": [{"t_s": t, "fds": f, "rss_kib": r >> 10} for t, f, r in samples],
        "rss_slope_kb_per_min": None if slope is None else round(slope / 1000, 2),
        "work": work,
        "failures": failures,
    }
    json.dump(report, sys.stdout, indent=1)
    print()
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
