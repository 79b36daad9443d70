"""A ROS 2 subscriber that is not sqscan: Eclipse Cyclone DDS (PyPI `cyclonedds`) with its own
IDL definitions of the messages, as ROS 2 maps them to DDS (topic `rt/<name>`, type
`<package>::msg::dds_::<Type>_`, plain CDR). Used by tests/service/ros2.rs, inside a private network
namespace with only loopback.

Usage: dds_sub.py SOCKET OBJECT SECONDS [DOMAIN]
       dds_sub.py --paced SOCKET SWEEPS SECONDS [DOMAIN]

Waits until the daemon's topics have matched, asks the daemon (its socket) to find
OBJECT, then prints one JSON object: the reply, and what arrived on each topic.

With --paced it reads the joint states, `/tf` and the clouds as a ROS 2 node at the default
QoS does (reliable, volatile, keep last 10), taking what has arrived every few milliseconds as
an executor would, while another thread asks the daemon for SWEEPS scans one after the other;
it prints the scans' replies and every message it received.
"""

import json
import math
import socket
import struct
import sys
import threading
import time
from dataclasses import dataclass

import cyclonedds.idl.annotations as annotate
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint32
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


def ros(package, name):
    return f"{package}::msg::dds_::{name}_"


@dataclass
@annotate.final
class Time(IdlStruct, typename=ros("builtin_interfaces", "Time")):
    sec: int32
    nanosec: uint32


@dataclass
@annotate.final
class Header(IdlStruct, typename=ros("std_msgs", "Header")):
    stamp: Time
    frame_id: str


@dataclass
@annotate.final
class PointField(IdlStruct, typename=ros("sensor_msgs", "PointField")):
    name: str
    offset: uint32
    datatype: uint8
    count: uint32


@dataclass
@annotate.final
class PointCloud2(IdlStruct, typename=ros("sensor_msgs", "PointCloud2")):
    header: Header
    height: uint32
    width: uint32
    fields: sequence[PointField]
    is_bigendian: bool
    point_step: uint32
    row_step: uint32
    data: sequence[uint8]
    is_dense: bool


@dataclass
@annotate.final
class JointState(IdlStruct, typename=ros("sensor_msgs", "JointState")):
    header: Header
    name: sequence[str]
    position: sequence[float64]
    velocity: sequence[float64]
    effort: sequence[float64]


@dataclass
@annotate.final
class Vector3(IdlStruct, typename=ros("geometry_msgs", "Vector3")):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Point(IdlStruct, typename=ros("geometry_msgs", "Point")):
    x: float64
    y: float64
    z: float64


@dataclass
@annotate.final
class Quaternion(IdlStruct, typename=ros("geometry_msgs", "Quaternion")):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
@annotate.final
class Pose(IdlStruct, typename=ros("geometry_msgs", "Pose")):
    position: Point
    orientation: Quaternion


@dataclass
@annotate.final
class Transform(IdlStruct, typename=ros("geometry_msgs", "Transform")):
    translation: Vector3
    rotation: Quaternion


@dataclass
@annotate.final
class TransformStamped(IdlStruct, typename=ros("geometry_msgs", "TransformStamped")):
    header: Header
    child_frame_id: str
    transform: Transform


@dataclass
@annotate.final
class TFMessage(IdlStruct, typename=ros("tf2_msgs", "TFMessage")):
    transforms: sequence[TransformStamped]


@dataclass
@annotate.final
class PoseWithCovariance(IdlStruct, typename=ros("geometry_msgs", "PoseWithCovariance")):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
@annotate.final
class ObjectHypothesis(IdlStruct, typename=ros("vision_msgs", "ObjectHypothesis")):
    class_id: str
    score: float64


@dataclass
@annotate.final
class ObjectHypothesisWithPose(IdlStruct, typename=ros("vision_msgs", "ObjectHypothesisWithPose")):
    hypothesis: ObjectHypothesis
    pose: PoseWithCovariance


@dataclass
@annotate.final
class BoundingBox3D(IdlStruct, typename=ros("vision_msgs", "BoundingBox3D")):
    center: Pose
    size: Vector3


@dataclass
@annotate.final
class Detection3D(IdlStruct, typename=ros("vision_msgs", "Detection3D")):
    header: Header
    results: sequence[ObjectHypothesisWithPose]
    bbox: BoundingBox3D
    id: str


@dataclass
@annotate.final
class Image(IdlStruct, typename=ros("sensor_msgs", "Image")):
    header: Header
    height: uint32
    width: uint32
    encoding: str
    is_bigendian: uint8
    step: uint32
    data: sequence[uint8]


@dataclass
@annotate.final
class ColorRGBA(IdlStruct, typename=ros("std_msgs", "ColorRGBA")):
    r: float32
    g: float32
    b: float32
    a: float32


@dataclass
@annotate.final
class Duration(IdlStruct, typename=ros("builtin_interfaces", "Duration")):
    sec: int32
    nanosec: uint32


@dataclass
@annotate.final
class CompressedImage(IdlStruct, typename=ros("sensor_msgs", "CompressedImage")):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
@annotate.final
class UVCoordinate(IdlStruct, typename=ros("visualization_msgs", "UVCoordinate")):
    u: float32
    v: float32


@dataclass
@annotate.final
class MeshFile(IdlStruct, typename=ros("visualization_msgs", "MeshFile")):
    filename: str
    data: sequence[uint8]


@dataclass
@annotate.final
class Marker(IdlStruct, typename=ros("visualization_msgs", "Marker")):
    header: Header
    ns: str
    id: int32
    type: int32
    action: int32
    pose: Pose
    scale: Vector3
    color: ColorRGBA
    lifetime: Duration
    frame_locked: bool
    points: sequence[Point]
    colors: sequence[ColorRGBA]
    texture_resource: str
    texture: CompressedImage
    uv_coordinates: sequence[UVCoordinate]
    text: str
    mesh_resource: str
    mesh_file: MeshFile
    mesh_use_embedded_materials: bool


@dataclass
@annotate.final
class MarkerArray(IdlStruct, typename=ros("visualization_msgs", "MarkerArray")):
    markers: sequence[Marker]


@dataclass
@annotate.final
class Detection3DArray(IdlStruct, typename=ros("vision_msgs", "Detection3DArray")):
    header: Header
    detections: sequence[Detection3D]


def ask(path, request):
    """One request on the daemon's socket, after its greeting line."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.connect(path)
        f = s.makefile("rwb")
        f.readline()
        f.write((json.dumps(request) + "\n").encode())
        f.flush()
        return json.loads(f.readline())


def stamp(h):
    return h.stamp.sec + 1e-9 * h.stamp.nanosec


def detection(d):
    """A Detection3D's one result: the object, its score and pose, and the box's size."""
    r = d.results[0]
    p, q = r.pose.pose.position, r.pose.pose.orientation
    return {
        "id": d.id,
        "class_id": r.hypothesis.class_id,
        "score": r.hypothesis.score,
        "position": [p.x, p.y, p.z],
        "orientation": [q.x, q.y, q.z, q.w],
        "bbox_size": [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z],
    }


def cloud_summary(m):
    fields = [{"name": f.name, "offset": f.offset, "datatype": f.datatype, "count": f.count} for f in m.fields]
    data = bytes(m.data)
    n = m.height * m.width
    finite = 0
    samples = []
    # Every 97th point, and its coordinates, to compare with the recording.
    for i in range(n):
        x, y, z = struct.unpack_from("<fff", data, i * m.point_step)
        if not math.isnan(x):
            finite += 1
            if i % 97 == 0:
                samples.append([i, x, y, z])
    return {
        "frame_id": m.header.frame_id,
        "stamp": stamp(m.header),
        "height": m.height,
        "width": m.width,
        "fields": fields,
        "is_bigendian": m.is_bigendian,
        "is_dense": m.is_dense,
        "point_step": m.point_step,
        "row_step": m.row_step,
        "bytes": len(data),
        "finite": finite,
        "samples": samples,
    }


def wait_matched(readers, seconds):
    """Waits up to SECONDS for every reader to match a writer; how many each matched."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        if all(r.get_subscription_matched_status().current_count > 0 for r in readers.values()):
            break
        time.sleep(0.05)
    return {k: r.get_subscription_matched_status().current_count for k, r in readers.items()}


def joint_state(m):
    return {"stamp": stamp(m.header), "name": list(m.name), "position": list(m.position)}


def tf_transforms(m):
    return [
        {
            "parent": t.header.frame_id,
            "child": t.child_frame_id,
            "stamp": stamp(t.header),
            "rotation": [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                         t.transform.rotation.w],
        }
        for t in m.transforms
    ]


def paced():
    path, sweeps, seconds = sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    domain = int(sys.argv[5]) if len(sys.argv) > 5 else 0
    dp = DomainParticipant(domain)
    # rclcpp's default: reliable, volatile, keep last 10.
    default = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.Durability.Volatile,
                  Policy.History.KeepLast(10))
    readers = {
        "joints": DataReader(dp, Topic(dp, "rt/sqscan/joint_states", JointState), qos=default),
        "tf": DataReader(dp, Topic(dp, "rt/tf", TFMessage), qos=default),
        "points": DataReader(dp, Topic(dp, "rt/sqscan/points", PointCloud2), qos=default),
        # As tf2's static listener subscribes.
        "tf_static": DataReader(dp, Topic(dp, "rt/tf_static", TFMessage),
                                qos=Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
                                        Policy.Durability.TransientLocal, Policy.History.KeepLast(100))),
    }
    t0 = time.monotonic()
    matched = wait_matched(readers, seconds)
    # The readers have matched the writers; a moment for the writers to match them.
    time.sleep(0.5)
    scans = []

    def ask_scans():
        for _ in range(sweeps):
            scans.append(ask(path, {"cmd": "scan", "timeout_s": seconds}))

    asking = threading.Thread(target=ask_scans)
    asking.start()
    got = {k: [] for k in readers}
    done_at = None
    while time.monotonic() - t0 < seconds:
        for k, r in readers.items():
            got[k].extend(r.take(N=100))
        if not asking.is_alive():
            done_at = done_at or time.monotonic()
            # The last sweep's cloud, and the samples after its last profile, still on their way.
            if time.monotonic() - done_at > 1.0:
                break
        time.sleep(0.005)
    asking.join(timeout=1)
    print(json.dumps({
        "matched": matched,
        "scans": scans,
        "joints": [joint_state(m) for m in got["joints"]],
        "tf": [tf_transforms(m) for m in got["tf"]],
        "clouds": [{"stamp": stamp(m.header), "height": m.height, "width": m.width} for m in got["points"]],
        "tf_static": [t for m in got["tf_static"] for t in tf_transforms(m)],
    }))


def main():
    if sys.argv[1] == "--paced":
        return paced()
    path, obj, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    domain = int(sys.argv[4]) if len(sys.argv) > 4 else 0
    dp = DomainParticipant(domain)
    reliable = Policy.Reliability.Reliable(duration(seconds=1))
    readers = {
        "points": DataReader(dp, Topic(dp, "rt/sqscan/points", PointCloud2), qos=Qos(reliable, Policy.History.KeepLast(2))),
        "joints": DataReader(dp, Topic(dp, "rt/sqscan/joint_states", JointState), qos=Qos(reliable, Policy.History.KeepLast(1000))),
        "detections": DataReader(dp, Topic(dp, "rt/sqscan/detections", Detection3DArray), qos=Qos(reliable, Policy.History.KeepLast(10))),
        "markers": DataReader(dp, Topic(dp, "rt/sqscan/markers", MarkerArray), qos=Qos(reliable, Policy.History.KeepLast(10))),
        "range": DataReader(dp, Topic(dp, "rt/sqscan/range", Image), qos=Qos(reliable, Policy.History.KeepLast(2))),
        "tf_static": DataReader(
            dp,
            Topic(dp, "rt/tf_static", TFMessage),
            qos=Qos(reliable, Policy.Durability.TransientLocal, Policy.History.KeepLast(1)),
        ),
        # Reliable and volatile as tf2's TransformListener subscribes; a sweep's transforms come
        # within tens of milliseconds, so the history holds them all, as for the joint states.
        "tf": DataReader(dp, Topic(dp, "rt/tf", TFMessage), qos=Qos(reliable, Policy.History.KeepLast(1000))),
    }
    t0 = time.monotonic()
    matched = wait_matched(readers, seconds)
    out = {"matched": matched, "match_s": time.monotonic() - t0}
    print(json.dumps({"progress": "matched", **matched}), file=sys.stderr, flush=True)
    out["reply"] = ask(path, {"cmd": "find", "object": obj, "timeout_s": 60})
    got = {k: [] for k in readers}
    while time.monotonic() - t0 < seconds:
        for k, r in readers.items():
            got[k].extend(r.take(N=1000))
        profiles = out["reply"].get("sweep", {}).get("profiles", 150)
        if (got["points"] and got["detections"] and got["tf_static"] and got["markers"] and got["range"]
                and len(got["joints"]) >= profiles and len(got["tf"]) >= profiles):
            break
        time.sleep(0.05)
    # A moment more for joint states of the same sweep still on their way.
    time.sleep(0.3)
    for k, r in readers.items():
        got[k].extend(r.take(N=1000))
    out["clouds"] = [cloud_summary(m) for m in got["points"]]
    out["joints"] = [joint_state(m) for m in got["joints"]]
    out["detections"] = [
        {
            "frame_id": m.header.frame_id,
            "stamp": stamp(m.header),
            "detections": [
                detection(d) for d in m.detections
            ],
        }
        for m in got["detections"]
    ]
    out["ranges"] = []
    for m in got["range"]:
        values = struct.unpack_from(f"<{m.height * m.width}f", bytes(m.data))
        out["ranges"].append({"frame_id": m.header.frame_id, "height": m.height, "width": m.width,
                              "encoding": m.encoding, "step": m.step,
                              "finite": sum(1 for v in values if not math.isnan(v))})
    out["markers"] = [
        [{"ns": k.ns, "id": k.id, "type": k.type, "action": k.action, "frame_id": k.header.frame_id,
          "points": [[p.x, p.y, p.z] for p in k.points], "z": k.pose.position.z,
          "color": [k.color.r, k.color.g, k.color.b, k.color.a]} for k in m.markers]
        for m in got["markers"]
    ]
    out["tf_static"] = [
        {
            "parent": t.header.frame_id,
            "child": t.child_frame_id,
            "translation": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
            "rotation": [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w],
        }
        for m in got["tf_static"]
        for t in m.transforms
    ]
    out["tf"] = [tf_transforms(m) for m in got["tf"]]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
