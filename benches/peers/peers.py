#!/usr/bin/env python3
"""Peer benchmark (issue 17): Open3D's global-registration pipeline against `sqscan detect`.

Both tools get the same simulated clouds (`sqscan simulate`, one per scene and seed) and the same
models (Open3D: the model's surface sampled by `sqscan show-model`; sqscan: the model file), in
one run, interleaved query by query so that a change of machine load hits both alike. Both are
scored against the simulator's truth with the rule of `sqscan eval` (src/eval/mod.rs,
src/symmetry.rs). Prints a markdown report and writes every trial to a JSON file.

Run with the venv made by benches/peers/setup.sh, from anywhere:
    target/peers-venv/bin/python benches/peers/peers.py [--seeds 5] [--voxel 5] [--voxel 3,5,8,10]
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import open3d as o3d

REPO = Path(__file__).resolve().parents[2]

# The scenes of the paper's tables and the models searched in them (issue 17).
DEFAULT_QUERIES = {
    "scenes/fig3_table.toml": ["bowl", "cup", "cup_body"],
    "scenes/fig4_tools.toml": ["mallet"],
}

# src/eval/mod.rs: MAX_POSITION_ERROR_M, MAX_ROTATION_ERROR_RAD. Copied, not parsed, so a change
# there must be made here too; the report prints them.
MAX_POSITION_ERROR_M = 0.010
MAX_ROTATION_ERROR_DEG = 10.0

MODEL_SPACING_M = 0.002

# A query counts as disturbed when other processes took more than this share of the CPU while it
# ran; it is then run again, up to QUERY_ATTEMPTS times in all (with --wait-quiet).
BUSY_SHARE = 0.10
QUERY_ATTEMPTS = 3


# ---------------------------------------------------------------------------------------------
# Rotations. Quaternions are [x, y, z, w] as in truth.json and sqscan's JSON.

def quat_to_matrix(q):
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def axis_angle_matrix(axis, angle):
    k = np.asarray(axis, dtype=float)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def rpy_matrix(roll, pitch, yaw):
    # src/pose.rs: REP-103 fixed axes X, then Y, then Z (nalgebra's from_euler_angles).
    return (axis_angle_matrix([0, 0, 1], yaw) @ axis_angle_matrix([0, 1, 0], pitch)
            @ axis_angle_matrix([1, 0, 0], roll))


def rotation_angle(r):
    return float(np.arccos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)))


def vector_angle(a, b):
    return float(np.arccos(np.clip(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0)))


def pose_from_spec(spec):
    """A TOML pose table (src/pose.rs PoseSpec) as a 4x4 matrix."""
    t = np.eye(4)
    spec = spec or {}
    t[:3, 3] = spec.get("position", [0.0, 0.0, 0.0])
    if "orientation" in spec:
        t[:3, :3] = quat_to_matrix(spec["orientation"])
    elif "rpy" in spec:
        t[:3, :3] = rpy_matrix(*spec["rpy"])
    elif "rpy_deg" in spec:
        t[:3, :3] = rpy_matrix(*np.radians(spec["rpy_deg"]))
    return t


def pose_from_json(pose):
    t = np.eye(4)
    t[:3, :3] = quat_to_matrix(pose["orientation"])
    t[:3, 3] = pose["position"]
    return t


# ---------------------------------------------------------------------------------------------
# Models, truth and symmetry: the same rules as sqscan's evaluator, so that both tools are scored
# alike and sqscan's figures here agree with `sqscan eval`.

class Model:
    def __init__(self, path):
        spec = tomllib.loads(Path(path).read_text())
        self.path = Path(path)
        self.name = spec.get("name", self.path.stem)
        self.parts = []
        for p in spec["part"]:
            self.parts.append({
                "name": p["name"],
                "shape": (tuple(p["a"]), p["e1"], p["e2"], p.get("kx", 0.0), p.get("ky", 0.0)),
                "open": p.get("open", False),
                "pose": pose_from_spec(p.get("pose")),
            })


def resolve_model(name_or_path, models_dir):
    p = Path(name_or_path)
    return p if p.suffix == ".toml" or p.exists() else Path(models_dir) / f"{name_or_path}.toml"


def same_shape(a, b):
    (aa, ae1, ae2, akx, aky), (ba, be1, be2, bkx, bky) = a, b
    return (all(abs(x - y) < 1e-9 for x, y in zip(aa, ba)) and abs(ae1 - be1) < 1e-9
            and abs(ae2 - be2) < 1e-9 and abs(akx - bkx) < 1e-9 and abs(aky - bky) < 1e-9)


def is_revolution(shape):
    a, _, e2, kx, ky = shape
    return abs(a[0] - a[1]) <= 1e-9 * max(a[0], a[1]) and abs(e2 - 1.0) < 1e-9 and abs(kx - ky) < 1e-12


def truth_pose(truth, model, models_dir):
    """src/eval/mod.rs truth_pose: the scene object of the same model, or else the object having a
    part of the model's first part's shape, at that part (cup_body is found as the cup's body)."""
    for o in truth["objects"]:
        if o["model"] == model.name:
            return o["name"], pose_from_json(o["pose"])
    first = model.parts[0]
    for o in truth["objects"]:
        scene_model = Model(resolve_model(o["model"], models_dir))
        for p in scene_model.parts:
            if same_shape(p["shape"], first["shape"]):
                part_pose = pose_from_json(o["pose"]) @ p["pose"]
                return o["name"], part_pose @ np.linalg.inv(first["pose"])
    raise SystemExit(f"no object of model {model.name!r} (or with its first part's shape) in {truth['scene']}")


class Symmetry:
    """src/symmetry.rs: a free spin about z when every part is a body of revolution on the object
    z axis, plus the half and quarter turns about x, y, z that map the model onto itself. Those
    turns are tested here on the surface samples of `sqscan show-model` instead of the exact
    surface distance; the tolerance separates the shipped models' cases by a wide margin (the
    report lists the turns found, to be checked against src/symmetry.rs's tests)."""

    def __init__(self, model, samples):
        self.spin_z = all(
            is_revolution(p["shape"])
            and np.linalg.norm(np.cross(p["pose"][:3, :3] @ [0, 0, 1], [0, 0, 1])) < 1e-9
            and abs(p["pose"][0, 3]) < 1e-9 and abs(p["pose"][1, 3]) < 1e-9
            for p in model.parts)
        self.discrete = [("identity", np.eye(3))]
        tree = o3d.geometry.KDTreeFlann(samples)
        points = np.asarray(samples.points)
        for axis_name, axis in (("x", [1, 0, 0]), ("y", [0, 1, 0]), ("z", [0, 0, 1])):
            for angle_name, angle in (("180", np.pi), ("90", np.pi / 2), ("-90", -np.pi / 2)):
                g = axis_angle_matrix(axis, angle)
                if self._maps_onto_itself(model, g, points, tree):
                    self.discrete.append((f"{angle_name} deg about {axis_name}", g))

    @staticmethod
    def _maps_onto_itself(model, g, points, tree):
        # An open part's opening is not a surface: a mug upside down is a mug on its rim.
        for p in model.parts:
            if p["open"]:
                moved_axis = g @ p["pose"][:3, :3] @ [0, 0, 1]
                if not any(q["open"] and same_shape(q["shape"], p["shape"])
                           and np.dot(q["pose"][:3, :3] @ [0, 0, 1], moved_axis) > 1 - 1e-6
                           for q in model.parts):
                    return False
        # Under a symmetry every moved sample lands within about one spacing of some sample (2.1-
        # 2.5 mm for the shipped models at 2 mm); under any other turn some land 17 mm or more
        # off (a handle turned away, a taper flipped). Three spacings sit well between the two.
        tol = 3 * MODEL_SPACING_M
        for x in points @ g.T:
            _, _, d2 = tree.search_knn_vector_3d(x, 1)
            if d2[0] > tol * tol:
                return False
        return True

    def rotation_error_deg(self, estimate, truth):
        best = np.inf
        for _, g in self.discrete:
            t = truth @ g
            if self.spin_z:
                err = vector_angle(estimate[:, 2], t[:, 2])
            else:
                err = rotation_angle(estimate.T @ t)
            best = min(best, err)
        return float(np.degrees(best))

    def describe(self):
        turns = ", ".join(name for name, _ in self.discrete[1:]) or "none"
        return f"{'free spin about z (axis only), ' if self.spin_z else ''}turns: {turns}"


def score(pose, found, truth, symmetry):
    if pose is None:
        return {"found": False, "correct": False, "position_error_m": None, "rotation_error_deg": None}
    pos = float(np.linalg.norm(pose[:3, 3] - truth[:3, 3]))
    rot = symmetry.rotation_error_deg(pose[:3, :3], truth[:3, :3])
    correct = bool(found and pos < MAX_POSITION_ERROR_M and rot < MAX_ROTATION_ERROR_DEG)
    return {"found": bool(found), "correct": correct, "position_error_m": pos, "rotation_error_deg": rot}


# ---------------------------------------------------------------------------------------------
# sqscan

def run(cmd, retries=60):
    """Runs a command; the other engineer may be rebuilding the binary under us, so a missing or
    busy executable is waited for rather than counted as a failure."""
    for attempt in range(retries):
        try:
            return subprocess.run(cmd, check=True, capture_output=True, text=True)
        except (FileNotFoundError, PermissionError, OSError) as e:
            if attempt == retries - 1:
                raise
            print(f"  ({cmd[0]}: {e}; retrying in 5 s)", file=sys.stderr)
            time.sleep(5)


def sqscan_detect(binary, model, cloud, seed, models_dir, repeat):
    """`repeat` runs of one query in one process, as Open3D's runs share this Python process:
    `timing_ms` is the fastest run's."""
    t0 = time.perf_counter()
    out = run([binary, "detect", "--model", model, "--cloud", str(cloud), "--seed", str(seed),
               "--models-dir", str(models_dir), "--repeat", str(repeat)])
    wall_ms = 1e3 * (time.perf_counter() - t0)
    d = json.loads(out.stdout.strip().splitlines()[-1])
    pose = pose_from_json(d["pose"]) if d.get("pose") else None
    return pose, bool(d.get("found")), d["timing_ms"]["total"], wall_ms, d


# ---------------------------------------------------------------------------------------------
# Open3D: the global-registration tutorial (RANSAC on FPFH, then ICP) with every length scaled to
# the voxel size v.

def kd(radius, max_nn):
    return o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn)


def prepare_model(samples, v):
    """The model side of the tutorial's preprocess_point_cloud. The model is known before any
    query, so this is not timed per query (in the peer's favour); its cost is reported apart."""
    t0 = time.perf_counter()
    down = samples.voxel_down_sample(v)
    down.estimate_normals(kd(2 * v, 30))
    fpfh = o3d.pipelines.registration.compute_fpfh_feature(down, kd(5 * v, 100))
    return down, fpfh, 1e3 * (time.perf_counter() - t0)


def open3d_detect(scene, samples, model_down, model_fpfh, v, seed, icp_on):
    reg = o3d.pipelines.registration
    # Every random choice (plane RANSAC, correspondence RANSAC) draws from Open3D's global
    # generator; seeding it per query makes a trial reproducible apart from thread scheduling.
    o3d.utility.random.seed(seed)
    t0 = time.perf_counter()
    _, inliers = scene.segment_plane(distance_threshold=v, ransac_n=3, num_iterations=1000)
    objects = scene.select_by_index(inliers, invert=True)
    t1 = time.perf_counter()
    down = objects.voxel_down_sample(v)
    down.estimate_normals(kd(2 * v, 30))
    fpfh = reg.compute_fpfh_feature(down, kd(5 * v, 100))
    t2 = time.perf_counter()
    ransac = reg.registration_ransac_based_on_feature_matching(
        model_down, down, model_fpfh, fpfh, True, 1.5 * v,
        reg.TransformationEstimationPointToPoint(False), 3,
        [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9), reg.CorrespondenceCheckerBasedOnDistance(1.5 * v)],
        reg.RANSACConvergenceCriteria(100000, 0.999))
    t3 = time.perf_counter()
    # The tutorial refines on the full clouds; point-to-plane needs the target's normals there.
    if icp_on == "full":
        source, target = samples, objects
        target.estimate_normals(kd(2 * v, 30))
    else:
        source, target = model_down, down
    icp = reg.registration_icp(source, target, 0.4 * v, ransac.transformation,
                               reg.TransformationEstimationPointToPlane())
    t4 = time.perf_counter()
    t = {"plane": t1 - t0, "features": t2 - t1, "ransac": t3 - t2, "icp": t4 - t3, "total": t4 - t0}
    t = {k: 1e3 * x for k, x in t.items()}
    # RANSAC always returns a transformation; with no inlier at all it is the identity, which is
    # the only case where the pipeline says "not found".
    found = ransac.fitness > 0
    info = {"ransac_fitness": ransac.fitness, "ransac_rmse": ransac.inlier_rmse,
            "icp_fitness": icp.fitness, "icp_rmse": icp.inlier_rmse, "points_off_plane": len(objects.points),
            "points_downsampled": len(down.points), "timing_ms": t}
    return np.asarray(icp.transformation).copy(), found, t["total"], info


# ---------------------------------------------------------------------------------------------
# Report

def quantile(values, q):
    """src/numeric/stats.rs quantile: the nearest rank, as `sqscan eval` reports."""
    v = sorted(x for x in values if x is not None and np.isfinite(x))
    if not v:
        return None
    return v[round((len(v) - 1) * q)]


def fmt(x, scale=1.0, digits=1):
    return "-" if x is None else f"{x * scale:.{digits}f}"


def load_average(label):
    return {f"load_{label}": [round(x, 2) for x in os.getloadavg()]}


class OtherLoad:
    """The share of the machine's CPU time used by processes other than this benchmark (and the
    sqscan processes it starts) while it ran: the load average lags by a minute and cannot tell
    our own work from, say, a build running beside us."""

    def __init__(self):
        self.t0, self.busy0, self.ours0 = time.perf_counter(), self._busy(), self._ours()

    @staticmethod
    def _busy():
        # /proc/stat cpu line: user nice system idle iowait irq softirq steal ... in clock ticks.
        f = [int(x) for x in Path("/proc/stat").read_text().splitlines()[0].split()[1:9]]
        return (f[0] + f[1] + f[2] + f[5] + f[6] + f[7]) / os.sysconf("SC_CLK_TCK")

    @staticmethod
    def _ours():
        t = os.times()
        return t.user + t.system + t.children_user + t.children_system

    def share(self):
        elapsed = time.perf_counter() - self.t0
        others = (self._busy() - self.busy0) - (self._ours() - self.ours0)
        return max(0.0, others / (elapsed * os.cpu_count()))


def wait_for_quiet(max_s):
    """Waits (at most max_s) until other processes use under a tenth of the CPU for half a
    second. Open3D's OpenMP threads slow down about twice as much as sqscan's rayon threads when
    a build shares the cores, so a busy machine would skew the ratio in sqscan's favour."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < max_s:
        probe = OtherLoad()
        time.sleep(0.5)
        if probe.share() < BUSY_SHARE:
            break
    return time.perf_counter() - t0


def cpu_model():
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def git_head():
    try:
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return head, bool(dirty)
    except OSError:
        return None, None


def binary_stamp(path):
    try:
        st = os.stat(path)
        return {"mtime": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(st.st_mtime)), "size": st.st_size}
    except OSError:
        return None


def summarize(rows):
    ok = [r for r in rows if r["correct"]]
    return {
        "correct": len(ok), "trials": len(rows), "found": sum(r["found"] for r in rows),
        "pos_med": quantile([r["position_error_m"] for r in ok], 0.5),
        "pos_p95": quantile([r["position_error_m"] for r in ok], 0.95),
        "rot_med": quantile([r["rotation_error_deg"] for r in ok], 0.5),
        "rot_p95": quantile([r["rotation_error_deg"] for r in ok], 0.95),
        "time_med": quantile([r["time_ms"] for r in rows], 0.5),
        "time_p95": quantile([r["time_ms"] for r in rows], 0.95),
        "wall_med": quantile([r.get("wall_ms") for r in rows], 0.5) if rows and "wall_ms" in rows[0] else None,
    }


def report(results, meta, voxels):
    out = []
    p = out.append
    p(f"Peer benchmark: Open3D {meta['open3d']} global registration vs sqscan detect")
    p("")
    head = meta["git_head"] + (" (work tree has uncommitted changes)" if meta["git_dirty"] else "")
    if meta["git_head_end"] != meta["git_head"]:
        head += f" at the start, {meta['git_head_end']} at the end"
    builds = ", ".join(f"{b} ({n} queries)" for b, n in meta["sqscan_builds"].items())
    p(f"- commit {head}; sqscan binary {meta['sqscan']} built {builds}"
      + (" (rebuilt during the run)" if len(meta["sqscan_builds"]) > 1 else ""))
    p(f"- machine: {meta['nproc']} cores, {meta['cpu']}; load average (1, 5, 15 min) at start "
      f"{meta['load_start']}, at end {meta['load_end']}; Python {meta['python']}, numpy {meta['numpy']}")
    p(f"- other processes' share of the CPU: {100 * meta['other_processes_cpu_share']:.0f} % over the whole run; "
      f"above 10 % during {meta['busy_queries']} of {meta['queries']} queries (each query waited up to "
      f"{meta['wait_quiet_s']:g} s for a quiet machine first)")
    p(f"- seeds {meta['seeds'][0]}..{meta['seeds'][-1]}: `sqscan simulate SCENE --seed S` makes one cloud per scene and seed; "
      f"sqscan runs `detect --seed S`, Open3D runs with `o3d.utility.random.seed(S)`; both use every core")
    p(f"- correct = found, position error < {MAX_POSITION_ERROR_M * 1e3:.0f} mm and rotation error < "
      f"{MAX_ROTATION_ERROR_DEG:.0f} deg, modulo the model's symmetries (as `sqscan eval`, src/eval/mod.rs); "
      "errors are over the correct trials only")
    if meta["busy_queries"]:
        p("- **some queries ran beside another busy process**: Open3D's OpenMP threads lose more than sqscan's to "
          "a process sharing the cores (about twice as slow beside a build, against about 1.5 times for sqscan), "
          "so those queries' ratios are too high (per-query shares in the JSON, `other_cpu_share`)")
    repeat = (f" (the least of {meta['repeat']} runs on the same cloud and seed, each tool's runs in one process: "
              f"sqscan's `detect --repeat {meta['repeat']}`, Open3D's in this Python process)") if meta["repeat"] > 1 else ""
    p(f"- time per query{repeat}: sqscan's `timing_ms.total` (detection, no file reading); Open3D's pipeline from plane "
      f"removal to the end of ICP on the scene already in memory (model features prepared once per voxel size, "
      f"not counted: {meta['model_prep']}); ICP on the {'full-resolution' if meta['icp_on'] == 'full' else 'downsampled'} clouds; "
      "ratio = Open3D median / sqscan median")
    p("")
    summary = []
    for model in meta["models"]:
        p(f"### {model} ({meta['symmetry'][model]}; truth object {meta['truth_object'][model]!r})")
        p("")
        p("| tool | voxel mm | correct | found | position error mm median / p95 | rotation error deg median / p95 | median ms | p95 ms | ratio |")
        p("|---|---|---|---|---|---|---|---|---|")
        s = summarize([r for r in results if r["model"] == model and r["tool"] == "sqscan"])
        p(f"| sqscan | - | {s['correct']} / {s['trials']} | {s['found']} | {fmt(s['pos_med'], 1e3, 2)} / {fmt(s['pos_p95'], 1e3, 2)} | "
          f"{fmt(s['rot_med'], 1, 2)} / {fmt(s['rot_p95'], 1, 2)} | {fmt(s['time_med'])} | {fmt(s['time_p95'])} | 1 |")
        peers = {}
        for v in voxels:
            o = summarize([r for r in results if r["model"] == model and r["tool"] == "open3d" and r["voxel_m"] == v])
            o["ratio"] = o["time_med"] / s["time_med"] if s["time_med"] else None
            peers[v] = o
            p(f"| Open3D | {v * 1e3:g} | {o['correct']} / {o['trials']} | {o['found']} | {fmt(o['pos_med'], 1e3, 2)} / {fmt(o['pos_p95'], 1e3, 2)} | "
              f"{fmt(o['rot_med'], 1, 2)} / {fmt(o['rot_p95'], 1, 2)} | {fmt(o['time_med'])} | {fmt(o['time_p95'])} | {fmt(o['ratio'])} |")
        p("")
        p(f"sqscan process wall time (start, file reading, {meta['repeat']} detection(s), exit): median {fmt(s['wall_med'])} ms")
        p("")
        # The peer's best setting: the most correct answers, then the fastest; when it is never
        # right, its fastest setting, so the ratio quoted is the least favourable to sqscan.
        best = max(voxels, key=lambda v: (peers[v]["correct"], -peers[v]["time_med"]))
        five = next((peers[v] for v in voxels if abs(v - 0.005) < 1e-9), None)
        summary.append((model, s, best, peers[best], five))
    p("### Summary")
    p("")
    p("| model | sqscan correct | sqscan median ms | Open3D 5 mm correct | Open3D 5 mm median ms | ratio at 5 mm "
      "| Open3D best voxel mm | its correct | its median ms | ratio at best |")
    p("|---|---|---|---|---|---|---|---|---|---|")
    for model, s, best, b, five in summary:
        f5 = (f"{five['correct']} / {five['trials']} | {fmt(five['time_med'])} | {fmt(five['ratio'])}"
              if five else "- | - | -")
        p(f"| {model} | {s['correct']} / {s['trials']} | {fmt(s['time_med'])} | {f5} | {best * 1e3:g} | "
          f"{b['correct']} / {b['trials']} | {fmt(b['time_med'])} | {fmt(b['ratio'])} |")
    p("")
    p("Best voxel: the most correct answers over the voxel sizes run, then the fastest. "
      "Ratio: Open3D median time / sqscan median time over the same clouds.")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------

def run_query(args, name, seed, scene, cloud_file, samples, prepared, voxels, true_pose, symmetry, base):
    """One query on one cloud: sqscan, then Open3D at each voxel size, each args.repeat times.
    Repeats are the same computation (same cloud, same seed): the answer is the first one's, the
    time the least, which a process beside us inflates the least."""
    rows = []
    pose, found, ms, wall_ms, raw = sqscan_detect(args.sqscan, name, cloud_file, seed, args.models_dir, args.repeat)
    r = {**base, "tool": "sqscan", "voxel_m": None, "time_ms": ms, "wall_ms": wall_ms,
         **score(pose, found, true_pose, symmetry),
         "pose": None if pose is None else pose.tolist(), "raw": raw,
         "sqscan_binary": (binary_stamp(args.sqscan) or {}).get("mtime")}
    rows.append(r)
    line = [f"seed {seed} {name:8s} sqscan {'ok ' if r['correct'] else 'MISS'} {ms:6.1f} ms"]
    for v in voxels:
        down, fpfh = prepared[name, v]
        runs = [open3d_detect(scene, samples, down, fpfh, v, seed, args.icp_on) for _ in range(args.repeat)]
        pose, found, _, info = runs[0]
        ms = min(x[2] for x in runs)
        # Open3D's parallel RANSAC can answer differently from run to run even when seeded; how
        # far the repeats' transforms differ is kept to show it.
        spread = max(float(np.abs(x[0] - pose).max()) for x in runs)
        r = {**base, "tool": "open3d", "voxel_m": v, "time_ms": ms, "times_ms": [x[2] for x in runs],
             "repeat_transform_spread": spread, **score(pose, found, true_pose, symmetry),
             "pose": pose.tolist(), **info}
        rows.append(r)
        line.append(f"o3d {v * 1e3:g}mm {'ok ' if r['correct'] else 'MISS'} {ms:6.0f} ms "
                    f"({fmt(r['position_error_m'], 1e3)} mm, {fmt(r['rotation_error_deg'])} deg)")
    return rows, line


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", "--trials", type=int, default=5, help="seeds 1..N, one trial each (default 5)")
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--sqscan", default=str(REPO / "target/release/sqscan"), help="sqscan binary")
    ap.add_argument("--models-dir", default=str(REPO / "models"))
    ap.add_argument("--models", help="comma-separated subset of bowl,cup,cup_body,mallet")
    ap.add_argument("--voxel", default="5", help="Open3D voxel size(s) in mm, comma-separated (default 5)")
    ap.add_argument("--icp-on", choices=["full", "down"], default="full",
                    help="ICP on the full-resolution clouds (the tutorial's) or the downsampled ones")
    ap.add_argument("--repeat", type=int, default=1,
                    help="run each query R times on the same cloud and seed; its time is the least (default 1)")
    ap.add_argument("--wait-quiet", type=float, default=60, metavar="S",
                    help="before each query wait up to S seconds for other processes to leave the CPU (default 60; 0: never)")
    ap.add_argument("--work", default=str(REPO / "target/peers"), help="simulated clouds and sampled models go here")
    ap.add_argument("--json", help="raw per-trial results (default WORK/results.json)")
    return ap.parse_args()


def main():
    args = parse_args()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    voxels = [float(x) * 1e-3 for x in args.voxel.split(",")]
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    wanted = set(args.models.split(",")) if args.models else None
    queries = {scene: [m for m in models if wanted is None or m in wanted] for scene, models in DEFAULT_QUERIES.items()}
    queries = {s: ms for s, ms in queries.items() if ms}
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    head, dirty = git_head()
    meta = {
        "open3d": o3d.__version__, "numpy": np.__version__, "python": platform.python_version(),
        "nproc": os.cpu_count(), "cpu": cpu_model(), "git_head": head, "git_dirty": dirty,
        "sqscan": os.path.relpath(args.sqscan, REPO), "sqscan_binary_start": binary_stamp(args.sqscan),
        "seeds": seeds, "voxels_m": voxels, "icp_on": args.icp_on, "repeat": args.repeat,
        "max_position_error_m": MAX_POSITION_ERROR_M, "max_rotation_error_deg": MAX_ROTATION_ERROR_DEG,
        "started": time.strftime("%Y-%m-%d %H:%M:%S"), **load_average("start"),
        "models": [m for ms in queries.values() for m in ms], "truth_object": {},
    }

    # Models: sampled once by sqscan, features once per voxel size.
    models, samples, prepared, prep_ms, symmetries = {}, {}, {}, {}, {}
    for name in meta["models"]:
        models[name] = Model(resolve_model(name, args.models_dir))
        ply = work / f"model_{name}.ply"
        run([args.sqscan, "show-model", name, "--out", str(ply), "--spacing", str(MODEL_SPACING_M),
             "--models-dir", args.models_dir])
        samples[name] = o3d.io.read_point_cloud(str(ply))
        for v in voxels:
            down, fpfh, ms = prepare_model(samples[name], v)
            prepared[name, v] = (down, fpfh)
            prep_ms[f"{name} {v * 1e3:g} mm"] = round(ms, 1)
        symmetries[name] = Symmetry(models[name], samples[name])
    meta["model_prep_ms"] = prep_ms
    meta["model_prep"] = f"{min(prep_ms.values()):.0f}-{max(prep_ms.values()):.0f} ms a model"

    other_load = OtherLoad()
    results = []
    for seed in seeds:
        for scene_file, names in queries.items():
            scene_dir = work / f"{Path(scene_file).stem}_seed{seed}"
            run([args.sqscan, "simulate", str(REPO / scene_file), "--out", str(scene_dir), "--seed", str(seed),
                 "--models-dir", args.models_dir])
            truth = json.loads((scene_dir / "truth.json").read_text())
            scene = o3d.io.read_point_cloud(str(scene_dir / "cloud.pcd"), remove_nan_points=True,
                                            remove_infinite_points=True)
            for name in names:
                model = models[name]
                obj, true_pose = truth_pose(truth, model, args.models_dir)
                meta["truth_object"][name] = obj
                base = {"scene": scene_file, "seed": seed, "model": name, "truth_object": obj,
                        "scene_points": len(scene.points)}
                # A query that another process disturbed is run again after waiting for quiet,
                # up to QUERY_ATTEMPTS times; the last attempt is kept whatever its share.
                attempts = QUERY_ATTEMPTS if args.wait_quiet > 0 else 1
                for attempt in range(1, attempts + 1):
                    waited = wait_for_quiet(args.wait_quiet) if args.wait_quiet > 0 else 0.0
                    query_load = OtherLoad()
                    query, line = run_query(args, name, seed, scene, scene_dir / "cloud.pcd", samples[name],
                                            prepared, voxels, true_pose, symmetries[name], base)
                    share = query_load.share()
                    if share <= BUSY_SHARE:
                        break
                for r in query:
                    r.update(other_cpu_share=round(share, 3), attempts=attempt, waited_for_quiet_s=round(waited, 1))
                results.extend(query)
                line.append(f"others {100 * share:.0f} %" + (f" (attempt {attempt})" if attempt > 1 else ""))
                print(" | ".join(line), file=sys.stderr)

    meta.update(load_average("end"))
    meta["other_processes_cpu_share"] = round(other_load.share(), 3)
    meta["wait_quiet_s"] = args.wait_quiet
    meta["busy_queries"] = sum(1 for r in results if r["tool"] == "sqscan" and r["other_cpu_share"] > BUSY_SHARE)
    meta["queries"] = sum(1 for r in results if r["tool"] == "sqscan")
    meta["sqscan_binary_end"] = binary_stamp(args.sqscan)
    meta["git_head_end"] = git_head()[0]
    meta["sqscan_builds"] = {}
    for r in results:
        if r["tool"] == "sqscan":
            meta["sqscan_builds"][r["sqscan_binary"]] = meta["sqscan_builds"].get(r["sqscan_binary"], 0) + 1
    meta["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    meta["symmetry"] = {k: s.describe() for k, s in symmetries.items()}
    text = report(results, meta, voxels)
    print(text)
    out = Path(args.json) if args.json else work / "results.json"
    out.write_text(json.dumps({"meta": meta, "trials": results}, indent=1))
    print(f"\nraw per-trial results: {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
