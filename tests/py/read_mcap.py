"""Reads an MCAP recording of sqscand with the PyPI `mcap` reader and `mcap-ros2-support`'s
decoder (independent of sqscan's encoder) and prints what it holds as one JSON object."""
import json
import math
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def stamp(h):
    return h.stamp.sec + h.stamp.nanosec * 1e-9


def main(path):
    out = {"topics": {}, "joint_states": [], "clouds": [], "detections": [], "metadata": {},
           "tf": [], "tf_static": [], "range": None, "markers": []}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        out["profile"] = header.profile
        for schema, channel, message, msg in reader.iter_decoded_messages():
            t = out["topics"].setdefault(channel.topic, {"schema": schema.name, "encoding": channel.message_encoding, "count": 0})
            t["count"] += 1
            if channel.topic == "/sqscan/joint_states":
                out["joint_states"].append({"names": list(msg.name), "position": list(msg.position), "stamp": stamp(msg.header), "log_time": message.log_time})
            elif channel.topic == "/sqscan/points":
                fields = [{"name": x.name, "offset": x.offset, "datatype": x.datatype, "count": x.count} for x in msg.fields]
                data = bytes(msg.data)
                import struct
                points = []
                for i in range(msg.height * msg.width):
                    x, y, z = struct.unpack_from("<fff", data, i * msg.point_step)
                    points.append([None if math.isnan(v) else v for v in (x, y, z)])
                out["clouds"].append({
                    "frame": msg.header.frame_id, "stamp": stamp(msg.header), "height": msg.height,
                    "width": msg.width, "point_step": msg.point_step, "row_step": msg.row_step,
                    "is_dense": msg.is_dense, "is_bigendian": msg.is_bigendian, "fields": fields,
                    "bytes": len(data), "points": points,
                })
            elif channel.topic == "/sqscan/detections":
                dets = []
                for d in msg.detections:
                    r = d.results[0]
                    p = r.pose.pose
                    dets.append({
                        "id": d.id, "class_id": r.hypothesis.class_id, "score": r.hypothesis.score,
                        "position": [p.position.x, p.position.y, p.position.z],
                        "orientation": [p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w],
                        "bbox_size": [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z],
                        "frame": d.header.frame_id,
                    })
                out["detections"].append({"frame": msg.header.frame_id, "stamp": stamp(msg.header), "detections": dets})
            elif channel.topic in ("/tf", "/tf_static"):
                out[channel.topic[1:]].append([
                    {"parent": t.header.frame_id, "child": t.child_frame_id,
                     "translation": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                     "rotation": [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                                  t.transform.rotation.w]}
                    for t in msg.transforms])
            elif channel.topic == "/sqscan/range":
                import struct
                values = struct.unpack_from(f"<{msg.height * msg.width}f", bytes(msg.data))
                out["range"] = {"frame": msg.header.frame_id, "height": msg.height, "width": msg.width,
                                "encoding": msg.encoding, "finite": sum(1 for v in values if not math.isnan(v))}
            elif channel.topic == "/sqscan/markers":
                out["markers"] = [{"ns": m.ns, "id": m.id, "type": m.type, "action": m.action,
                                   "points": len(m.points), "z": m.pose.position.z} for m in msg.markers]
        for m in reader.iter_metadata():
            out["metadata"][m.name] = dict(m.metadata)
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
