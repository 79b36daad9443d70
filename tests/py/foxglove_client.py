"""A Foxglove WebSocket client written from the protocol's description, with PyPI `websockets`
(subprotocol foxglove.sdk.v1, the Foxglove WebSocket protocol under its current name): reads the server's info and advertised channels, subscribes
to every channel, prints "subscribed", then decodes the messages it gets with
mcap-ros2-support's ROS 2 decoder (independent of sqscan's encoder) until it has a cloud, its
range image, the rig's transforms, a detection array and its markers, and prints what it saw as
one JSON object."""
import asyncio
import json
import math
import struct
import sys

import websockets
from mcap_ros2._dynamic import generate_dynamic


async def main(url, timeout):
    out = {"server_info": None, "channels": [], "points": None, "detections": [], "joint_states": 0,
           "last_joint_state": None, "range": None, "tf": 0, "last_tf": None, "tf_static": None, "markers": None}
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
        out["subprotocol"] = ws.subprotocol
        channels = {}
        while out["server_info"] is None or len(channels) < 7:
            msg = json.loads(await asyncio.wait_for(ws.recv(), timeout))
            if msg["op"] == "serverInfo":
                out["server_info"] = msg
            elif msg["op"] == "advertise":
                for c in msg["channels"]:
                    channels[c["id"]] = c
        out["channels"] = sorted(
            ({"topic": c["topic"], "encoding": c["encoding"], "schemaName": c["schemaName"],
              "schemaEncoding": c.get("schemaEncoding")} for c in channels.values()),
            key=lambda c: c["topic"])
        subs = {}
        decoders = {}
        for i, c in enumerate(channels.values(), start=1):
            subs[i] = c
            decoders[i] = generate_dynamic(c["schemaName"], c["schema"])[c["schemaName"]]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": c["id"]} for i, c in subs.items()]}))
        print("subscribed", flush=True)
        def pose(p):
            return {"position": [p.position.x, p.position.y, p.position.z],
                    "orientation": [p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w]}

        def transforms(m):
            return [{"parent": t.header.frame_id, "child": t.child_frame_id,
                     "translation": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                     "rotation": [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                                  t.transform.rotation.w],
                     "stamp": t.header.stamp.sec + 1e-9 * t.header.stamp.nanosec} for t in m.transforms]

        while (out["points"] is None or not out["detections"] or out["markers"] is None or out["range"] is None
               or out["tf_static"] is None):
            data = await asyncio.wait_for(ws.recv(), timeout)
            if isinstance(data, str):
                continue
            assert data[0] == 0x01, f"opcode {data[0]}"
            sub, log_time = struct.unpack_from("<IQ", data, 1)
            msg = decoders[sub](data[13:])
            topic = subs[sub]["topic"]
            if topic == "/sqscan/points":
                step = msg.point_step
                raw = bytes(msg.data)
                pts = [struct.unpack_from("<fff", raw, k * step) for k in range(msg.height * msg.width)]
                out["points"] = {
                    "frame": msg.header.frame_id, "height": msg.height, "width": msg.width,
                    "fields": [f.name for f in msg.fields], "is_dense": msg.is_dense,
                    "finite": sum(1 for p in pts if not math.isnan(p[0])),
                    "first_finite": next([float(v) for v in p] for p in pts if not math.isnan(p[0])),
                    "log_time": log_time,
                }
            elif topic == "/sqscan/detections":
                out["detections"].append([
                    {"class_id": d.results[0].hypothesis.class_id, "score": d.results[0].hypothesis.score,
                     "position": [d.results[0].pose.pose.position.x, d.results[0].pose.pose.position.y,
                                  d.results[0].pose.pose.position.z]}
                    for d in msg.detections])
            elif topic == "/sqscan/joint_states":
                out["joint_states"] += 1
                out["last_joint_state"] = {"name": list(msg.name), "position": list(msg.position),
                                           "stamp": msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec}
            elif topic == "/sqscan/range":
                raw = bytes(msg.data)
                values = struct.unpack_from(f"<{msg.height * msg.width}f", raw)
                out["range"] = {"frame": msg.header.frame_id, "height": msg.height, "width": msg.width,
                                "encoding": msg.encoding, "step": msg.step, "bytes": len(raw),
                                "finite": sum(1 for v in values if not math.isnan(v)),
                                "min": min(v for v in values if not math.isnan(v)),
                                "max": max(v for v in values if not math.isnan(v))}
            elif topic == "/tf":
                out["tf"] += 1
                out["last_tf"] = transforms(msg)
            elif topic == "/tf_static":
                out["tf_static"] = transforms(msg)
            elif topic == "/sqscan/markers":
                out["markers"] = [
                    {"ns": m.ns, "id": m.id, "type": m.type, "action": m.action, "frame": m.header.frame_id,
                     "pose": pose(m.pose), "scale": [m.scale.x, m.scale.y, m.scale.z],
                     "color": [m.color.r, m.color.g, m.color.b, m.color.a],
                     "points": [[p.x, p.y, p.z] for p in m.points]}
                    for m in msg.markers]
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], float(sys.argv[2])))
