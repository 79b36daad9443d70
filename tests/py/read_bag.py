"""Opens a recording directory of sqscand as a rosbag2 bag with PyPI `rosbags` (independent of
sqscan), then writes the same messages with rosbags' own rosbag2 writer into OUT and opens that
too, and prints one JSON object: the bag's topics with their QoS and counts, what its clouds and
detections decode to, whether every MCAP file's messages are in log-time order in the file, and
every difference between the two bags in what rosbags' reader takes from them.

Usage: read_bag.py DIR OUT
"""

import json
import sys
from pathlib import Path

from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore


def qos_json(q):
    return {
        "history": q.history.name.lower(),
        "depth": q.depth,
        "reliability": q.reliability.name.lower(),
        "durability": q.durability.name.lower(),
        "liveliness": q.liveliness.name.lower(),
    }


def summary(reader):
    """What rosbags' reader takes from a bag's metadata."""
    return {
        "duration": reader.duration,
        "start_time": reader.start_time,
        "end_time": reader.end_time,
        "message_count": reader.message_count,
        "compression_format": reader.compression_format,
        "compression_mode": reader.compression_mode,
        "topics": {
            c.topic: {
                "type": c.msgtype,
                "count": c.msgcount,
                "serialization_format": c.ext.serialization_format,
                "qos": [qos_json(q) for q in c.ext.offered_qos_profiles],
            }
            for c in reader.connections
        },
    }


def messages(reader):
    return [(c.topic, t, bytes(data)) for c, t, data in reader.messages()]


def main(path, out_path):
    path, out_path = Path(path), Path(out_path)
    out = {}
    with Reader(path) as reader:
        ours = summary(reader)
        ours_messages = messages(reader)
        connections = list(reader.connections)
    out["bag"] = ours
    out["in_time_order"] = all(a[1] <= b[1] for a, b in zip(ours_messages, ours_messages[1:]))

    # The MCAP files themselves, in file order: rosbag2 writes messages as they come.
    out["files_in_log_time_order"] = {}
    for f in sorted(path.glob("*.mcap")):
        with f.open("rb") as stream:
            times = [m.log_time for _, _, m in make_reader(stream).iter_messages(log_time_order=False)]
        out["files_in_log_time_order"][f.name] = all(a <= b for a, b in zip(times, times[1:]))

    # Decoded, with the message definitions the bag carries (vision_msgs is no Humble core type).
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        out["clouds"] = []
        out["detections"] = []
        for c, t, data in reader.messages():
            if c.topic == "/sqscan/points":
                msg = reader.deserialize(data, c.msgtype)
                out["clouds"].append({
                    "t": t, "frame": msg.header.frame_id, "height": msg.height, "width": msg.width,
                    "stamp": msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec,
                })
            elif c.topic == "/sqscan/detections":
                msg = reader.deserialize(data, c.msgtype)
                out["detections"].append({
                    "t": t,
                    "found": [
                        {"class": d.results[0].hypothesis.class_id,
                         "position": [d.results[0].pose.pose.position.x, d.results[0].pose.pose.position.y,
                                      d.results[0].pose.pose.position.z]}
                        for d in msg.detections
                    ],
                })

    # The same messages through rosbags' own writer (its MCAP storage, its newest format).
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(out_path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        theirs = {}
        for c in connections:
            theirs[c.topic] = writer.add_connection(
                # The type hash (newer bags' field) is not what the comparison is about.
                c.topic, c.msgtype, msgdef=c.msgdef.data, rihs01=c.digest or "RIHS01_" + "0" * 64,
                serialization_format=c.ext.serialization_format,
                offered_qos_profiles=c.ext.offered_qos_profiles, typestore=typestore,
            )
        for topic, t, data in ours_messages:
            writer.write(theirs[topic], t, data)
    with Reader(out_path) as reader:
        theirs_summary = summary(reader)
        theirs_messages = messages(reader)

    differences = []
    for key in ours:
        if ours[key] != theirs_summary[key]:
            differences.append({"field": key, "ours": ours[key], "rosbags": theirs_summary[key]})
    if ours_messages != theirs_messages:
        differences.append({"field": "messages", "ours": len(ours_messages), "rosbags": len(theirs_messages)})
    out["differences"] = differences
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
